"""One constructor for the training envs (uamfleet.env.backends.make_vector) and the training option that picks
its backend (--vector-backend): every backend shows one interface and steps the same envs, and a backend that
contradicts the other options is refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import small_config

from uamfleet.config import ConfigError, Request
from uamfleet.env.backends import InlineVectorEnv, VectorBackend, make_vector, resolve_backend
from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.workers import ShardedVectorEnv
from uamfleet.presets import make_config
from uamfleet.rl.collector import make_run
from uamfleet.rl.distributed import Ranks
from uamfleet.rl.options import TrainArgs


def _fleet(taxis: int, **options: object) -> object:
    return make_config("berlin_fleet", num_taxis=taxis, **options).replace(time_limit_steps=25)


def test_every_backend_shows_one_interface_and_steps_the_same_envs() -> None:
    cfg = _fleet(2)
    inline = make_vector(cfg, 3)  # auto: one config, no workers
    mixture = make_vector([cfg], 3, "mixture")
    workers = make_vector([cfg], 3, workers=2, global_state=True)  # auto: workers
    assert type(inline) is InlineVectorEnv and type(mixture) is MixtureVectorEnv and type(workers) is ShardedVectorEnv
    try:
        for venv in (inline, mixture, workers):
            assert isinstance(venv, VectorBackend)
            assert venv.taxis_per_env.tolist() == [2, 2, 2] and venv.mixed_sizes is False
            assert (venv.num_envs, venv.num_taxis) == (3, 2)
        assert inline.envs == [inline] and len(mixture.envs) == 1 and workers.envs == []
        first = [venv.reset(seed=4)[0] for venv in (inline, mixture, workers)]
        for key in first[0]:
            for other in first[1:]:
                np.testing.assert_array_equal(first[0][key], other[key], err_msg=key)
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(30):  # past the 25-step limit: every env ends an episode and starts again
            actions = rng.integers(0, 16, (3, 2))
            steps = [venv.step(actions) for venv in (inline, mixture, workers)]
            for other in steps[1:]:
                for key in steps[0][0]:
                    np.testing.assert_array_equal(steps[0][0][key], other[0][key], err_msg=key)
                for i in (1, 2, 3):
                    np.testing.assert_array_equal(steps[0][i], other[i])
            ended += int((steps[0][2] | steps[0][3]).sum())
            states = [venv.global_state() for venv in (inline, mixture, workers)]
            np.testing.assert_array_equal(states[0], states[1])
            np.testing.assert_array_equal(states[0], states[2])
        assert ended >= 3
    finally:
        for venv in (inline, mixture, workers):
            venv.close()
    workers.close()  # closing twice is harmless
    with pytest.raises(RuntimeError, match="closed"):
        workers.reset(seed=0)


def test_auto_mixes_several_configs_and_reports_their_fleets() -> None:
    venv = make_vector([_fleet(1, passenger_window=8), _fleet(3, passenger_window=8)], 3)
    assert type(venv) is MixtureVectorEnv
    assert venv.mixed_sizes is True and venv.taxis_per_env.tolist() == [1, 1, 3] and venv.num_taxis == 3


@pytest.mark.parametrize(
    ("backend", "configs", "workers", "message"),
    [
        ("threads", 1, 0, r"backend='threads' is unknown; use one of \['auto', 'inline', 'mixture', 'workers'\]"),
        ("workers", 1, 0, r"backend='workers' .* give workers >= 1"),
        ("mixture", 2, 2, r"backend='mixture' steps the envs in this process, but workers=2"),
        ("inline", 3, 0, r"backend='inline' steps one config, not 3; use backend 'mixture'"),
    ],
)
def test_a_backend_that_contradicts_its_inputs_is_refused(backend: str, configs: int, workers: int, message: str):
    with pytest.raises(ConfigError, match=message):
        resolve_backend(backend, configs, workers)


def test_auto_is_todays_choice() -> None:
    assert [resolve_backend("auto", n, w) for n, w in [(1, 0), (2, 0), (1, 1), (3, 2)]] == [
        "inline", "mixture", "workers", "workers",
    ]  # fmt: skip
    assert resolve_backend("mixture", 1, 0) == "mixture"  # one config's group, in this process


def _args(**overrides: object) -> TrainArgs:
    return TrainArgs.from_flat({"num_envs": 4, **overrides})


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"vector_backend": "workers"}, r"^--vector-backend workers .* give --env-workers >= 1 \(or use auto\)\.$"),
        ({"vector_backend": "inline", "env_workers": 2}, r"^--vector-backend inline .* --env-workers=2 asks for"),
        ({"vector_backend": "mixture", "env_workers": 1}, r"^--vector-backend mixture .* --env-workers=1 asks for"),
        ({"vector_backend": "inline", "thresholds": (-7.0, -5.0)}, r"give 2; use --vector-backend mixture"),
        (
            {"vector_backend": "inline", "scenario": "berlin_fleet", "fleet_mixture": ("1x6", "2x24")},
            r"give 2; use --vector-backend mixture",
        ),
        ({"vector_backend": "sharded"}, r"^--vector-backend='sharded' is unknown; use auto, inline, mixture"),
    ],
)
def test_the_training_option_refuses_a_backend_that_contradicts_the_others(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        _args(**overrides)
    assert "\n" not in str(err.value)


def test_the_training_option_resolves_auto_and_old_checkpoints_read_as_auto() -> None:
    assert _args().chosen_backend() == "inline"
    assert _args(env_workers=2).chosen_backend() == "workers"
    assert _args(thresholds=(-5.0,)).chosen_backend() == "mixture"
    assert _args(thresholds=(-5.0,), vector_backend="inline").chosen_backend() == "inline"
    saved = _args(env_workers=2).flat()
    assert saved["vector_backend"] == "auto"
    del saved["vector_backend"]  # a checkpoint written before the option
    restored = TrainArgs.from_saved(saved)
    assert restored.env.vector_backend == "auto" and restored.chosen_backend() == "workers"


def test_a_run_steps_its_envs_with_the_backend_it_names(tmp_path) -> None:  # type: ignore[no-untyped-def]
    cfg = small_config(requests=(Request(0, (350.0, 150.0), (350.0, 350.0)),), time_limit_steps=6)
    common = dict(num_envs=3, num_steps=8, total_timesteps=24, num_minibatches=1, run_dir=tmp_path, progress=False,
                  tensorboard=False, threads=1)  # fmt: skip
    inline = make_run(TrainArgs.from_flat(common), cfg, Ranks(), torch.device("cpu")).venv
    mixture = make_run(TrainArgs.from_flat({**common, "vector_backend": "mixture"}), cfg, Ranks(), torch.device("cpu"))
    assert type(inline) is InlineVectorEnv and type(mixture.venv) is MixtureVectorEnv
    a, b = inline.reset(seed=2)[0], mixture.venv.reset(seed=2)[0]
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert mixture.agent_rows is None  # one fleet size: every column a real taxi
