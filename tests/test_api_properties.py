"""Property test (Hypothesis) of the public API's own arguments (issue 22, part 6): ``make_config``,
``parallel_env``, ``vector_env`` (and ``reset(seed=...)`` of both envs), ``make_instance``,
``make_fleet_instance`` and ``load_radio_map``, each argument given a drawn value, sensible or not. Every call
either works, and then the value is kept exactly (never clamped or rounded), or raises a ``ValueError``
(``ConfigError`` is one) whose message names the argument: never another exception and never a hang.
``tests/env/test_properties.py`` covers every EnvConfig field on a drawn map; this one covers the entry points
on the packaged maps. ``PROBED`` replays, one by one, the inputs of the issue's probe that once ended in a
TypeError / OverflowError / MemoryError or were silently accepted.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import uamfleet
from tests.env.test_properties import time_limit  # SIGALRM: fail instead of hanging
from uamfleet.checks import MAX_ENVS
from uamfleet.instances import make_fleet_instance, make_instance

JUNK = [math.nan, math.inf, -math.inf, "3", "", None, True, False, (1, 2), [], 1e300, -1e300, -1, 0, 2.5, 10**12]


def config_field(scenario: str, name: str) -> Callable[[Any], Any]:
    """make_config(scenario, name=value); the value must come back exactly when it is accepted."""

    def call(value: Any) -> Any:
        cfg = uamfleet.make_config(scenario, **{name: value})
        kept = getattr(cfg, name)
        assert kept == value or (isinstance(value, float) and math.isnan(value) and math.isnan(kept)), (
            f"{name}={value!r} was accepted as {kept!r}"
        )
        return cfg

    return call


def vector_env_argument(name: str) -> Callable[[Any], Any]:
    """vector_env("berlin_p4", name=value); the value must come back exactly on the env when it is accepted."""

    def call(value: Any) -> Any:
        venv = uamfleet.vector_env("berlin_p4", **{name: value})
        kept = getattr(venv, name)
        assert kept == value and type(kept) is (bool if name == "autoreset" else int), (
            f"{name}={value!r} was accepted as {kept!r}"
        )
        return venv

    return call


def reset_seed(make: Callable[[], Any]) -> Callable[[Any], Any]:
    """``env.reset(seed=value)`` on one env made on the first call (building an env per drawn value is slow)."""
    made: list[Any] = []

    def call(value: Any) -> Any:
        if not made:
            made.append(make())
        return made[0].reset(seed=value)

    return call


Case = tuple[str, str, Callable[[Any], Any], st.SearchStrategy[Any]]
"""(label, the argument's name as the message must say it, call with the drawn value, sensible values)"""


def keyword(
    function: Callable[..., Any], name: str, sensible: st.SearchStrategy[Any], *args: Any, **fixed: Any
) -> Case:
    """The case ``function(*args, **fixed, name=value)``."""
    return f"{function.__name__} {name}", name, lambda v: function(*args, **fixed, **{name: v}), sensible


def field(scenario: str, name: str, sensible: st.SearchStrategy[Any]) -> Case:
    return f"make_config {name}", name, config_field(scenario, name), sensible


SEEDS = st.one_of(st.none(), st.integers(0, 2**63 - 1))
FLEET = {"family": "berlin", "seed": 3, "num_taxis": 2, "num_requests": 4}
CASES: list[Case] = [
    keyword(uamfleet.make_config, "scenario", st.sampled_from(uamfleet.SCENARIOS)),
    field("berlin_p4", "sinr_min_db", st.floats(-30, 30)),
    field("berlin_random", "num_taxis", st.integers(1, 8)),
    field("berlin_p4", "seats", st.integers(1, 4)),
    field("berlin_p4", "time_limit_steps", st.integers(1, 2000)),
    field("berlin_p4", "history_len", st.integers(1, 8)),
    field("berlin_p4", "patch_size", st.integers(1, 12)),
    field("berlin_p4", "step_m", st.sampled_from([50.0, 100.0, 150.0])),
    field("berlin_p4", "slot_s", st.floats(0.5, 10)),
    field("berlin_p4", "max_passengers", st.integers(4, 12)),
    field("berlin_fleet", "min_separation_m", st.floats(0, 300)),
    keyword(uamfleet.parallel_env, "render_mode", st.none(), "berlin_p4"),  # not "human": it opens a viewer
    keyword(uamfleet.parallel_env, "sinr_min_db", st.floats(-10, 0), "berlin_p4"),
    ("vector_env num_envs", "num_envs", vector_env_argument("num_envs"), st.integers(1, 8)),
    ("vector_env autoreset", "autoreset", vector_env_argument("autoreset"), st.booleans()),
    ("VectorEnv.reset seed", "seed", reset_seed(lambda: uamfleet.vector_env("berlin_p4", num_envs=2)), SEEDS),
    ("ParallelEnv.reset seed", "seed", reset_seed(lambda: uamfleet.parallel_env("berlin_p4")), SEEDS),
    keyword(make_instance, "family", st.sampled_from(["berlin", "detroit3gpp"]), seed=7),
    keyword(make_instance, "seed", st.integers(0, 10**9), "berlin"),
    keyword(make_instance, "feasibility", st.sampled_from(["endpoint_block", "segment_raster"]), "berlin", 7),
    keyword(make_instance, "max_passengers", st.one_of(st.none(), st.integers(6, 12)), "berlin", 7),
    *(
        keyword(make_fleet_instance, name, sensible, **{k: v for k, v in FLEET.items() if k != name})
        for name, sensible in (
            ("seed", st.integers(0, 10**9)),
            ("num_taxis", st.integers(1, 6)),
            ("num_requests", st.integers(1, 12)),
            ("num_vertiports", st.integers(0, 6)),
            ("arrival_window_s", st.floats(1, 3600)),
            ("max_passengers", st.one_of(st.none(), st.integers(4, 9))),
        )
    ),
    (
        "load_radio_map name",
        "load_radio_map",
        uamfleet.load_radio_map,
        st.sampled_from([*uamfleet.RADIO_MAPS, "no_such_map", "missing/file.txt"]),
    ),
]


ANY_VALUE = st.one_of(st.sampled_from(JUNK), st.integers(-10, 10**7), st.text(max_size=12))
# num_envs: every accepted value allocates that many envs, so the draws stay small or past the bound (MAX_ENVS).
OTHER_VALUES: dict[str, st.SearchStrategy[Any]] = {
    "vector_env num_envs": st.one_of(
        st.sampled_from(JUNK), st.integers(-10, 64), st.integers(MAX_ENVS + 1, 10**13), st.text(max_size=12)
    ),
}


@pytest.mark.parametrize("case", CASES, ids=[case[0] for case in CASES])
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(data=st.data())
def test_every_argument_works_exactly_or_is_refused_by_name(case: Case, data: st.DataObject):
    """Each argument on its own draws (sampling the arguments too left some without a single draw)."""
    label, name, call, sensible = case
    value = data.draw(st.one_of(sensible, OTHER_VALUES.get(label, ANY_VALUE)), label=name)
    try:
        with time_limit(60):
            call(value)
    except ValueError as err:  # ConfigError, InfeasibleInstanceError, ... are ValueErrors
        message = str(err)
        assert message and (name in message or name == "load_radio_map"), f"{label}={value!r}: {message!r}"


# The probe's inputs (issue 22) that once ended in a TypeError / OverflowError / MemoryError or were accepted:
# (argument the message must name, call).
def p4_vector_env(**arguments: Any) -> Any:
    return uamfleet.vector_env("berlin_p4", **arguments)


PROBED: list[tuple[str, str, Callable[[], Any]]] = [
    ("vector_env num_envs=True (was accepted)", "num_envs", lambda: p4_vector_env(num_envs=True)),
    ("vector_env num_envs=None (TypeError)", "num_envs", lambda: p4_vector_env(num_envs=None)),
    ("vector_env num_envs=inf (OverflowError)", "num_envs", lambda: p4_vector_env(num_envs=math.inf)),
    ("vector_env num_envs=10**12 (MemoryError)", "num_envs", lambda: p4_vector_env(num_envs=10**12)),
    ("vector_env autoreset='no' (taken as true)", "autoreset", lambda: p4_vector_env(autoreset="no")),
    ("VectorEnv.reset seed=True (was accepted)", "seed", lambda: p4_vector_env().reset(seed=True)),
    ("VectorEnv.reset seed=inf (OverflowError)", "seed", lambda: p4_vector_env().reset(seed=math.inf)),
    ("ParallelEnv.reset seed=True (was accepted)", "seed", lambda: uamfleet.parallel_env("berlin_p4").reset(seed=True)),
    ("ParallelEnv.reset seed=inf (OverflowError)", "seed", lambda: uamfleet.parallel_env().reset(seed=math.inf)),
    ("make_config scenario=[] (TypeError: unhashable)", "scenario", lambda: uamfleet.make_config([])),
    ("make_instance family=[] (TypeError: unhashable)", "family", lambda: make_instance([], 1)),
    ("load_radio_map(None) (TypeError)", "load_radio_map", lambda: uamfleet.load_radio_map(None)),
    ("load_radio_map(3.0) (TypeError)", "load_radio_map", lambda: uamfleet.load_radio_map(3.0)),
    ("make_fleet_instance num_taxis=885 (RuntimeError)", "num_taxis", lambda: make_fleet_instance("berlin", 3, 885, 4)),
    ("make_fleet_instance num_vertiports=885 (numpy)", "num_vertiports",
     lambda: make_fleet_instance("berlin", 3, 2, 4, num_vertiports=885)),
    ("make_fleet_instance arrival_window_s=1e300 (numpy)", "arrival_window_s",
     lambda: make_fleet_instance("berlin", 3, 2, 4, arrival_window_s=1e300)),
]  # fmt: skip


@pytest.mark.parametrize(("name", "call"), [c[1:] for c in PROBED], ids=[c[0] for c in PROBED])
def test_probed_inputs_are_refused_in_one_line_naming_the_argument(name: str, call: Callable[[], Any]):
    with time_limit(60), pytest.raises(ValueError) as refused:
        call()
    message = str(refused.value)
    assert name in message and "\n" not in message, message


def test_num_envs_is_accepted_up_to_its_documented_bound_only():
    """MAX_ENVS is the bound the message names: one more is refused before anything is allocated."""
    with pytest.raises(ValueError, match=rf"num_envs={MAX_ENVS + 1} is too large: at most {MAX_ENVS}"):
        uamfleet.vector_env("berlin_p4", num_envs=MAX_ENVS + 1)
    assert uamfleet.vector_env("berlin_p4", num_envs=64).num_envs == 64
