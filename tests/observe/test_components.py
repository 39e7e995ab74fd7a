"""The planner-derived components fill their distance-table rows before any kernel runs (``prepare``), so each
kernel runs once per observation and a missing row is a bug that raises, never a second call."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import small_config

from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.observe import stops as stop_kernels
from uamfleet.observe.stops import StopsComponent

OPEN_7 = "\n".join(["......."] * 7)
REQUESTS = (
    Request(0, (250.0, 250.0), (550.0, 450.0)),
    Request(0, (450.0, 150.0), (150.0, 550.0)),
    Request(2, (650.0, 650.0), (50.0, 50.0)),
)


def env_on_a_new_map(**overrides: Any) -> VectorEnv:
    """An env on a map object of its own, so its distance table starts with no row filled."""
    cfg = small_config(OPEN_7, starts_m=None, num_taxis=2, requests=REQUESTS, seats=1, patch_size=3,
                       stop_features=True, stop_rivals=True, **overrides)  # fmt: skip
    return VectorEnv(cfg)


def counting(monkeypatch: pytest.MonkeyPatch, name: str) -> list[bool]:
    kernel = getattr(stop_kernels, name)
    calls: list[bool] = []

    def counted(*args: Any) -> bool:
        calls.append(bool(kernel(*args)))
        return calls[-1]

    monkeypatch.setattr(stop_kernels, name, counted)
    return calls


@pytest.mark.parametrize("overrides", [{}, {"heading_lookahead": True, "lookahead_depth": 2}, {"passenger_window": 2}])
def test_each_stop_kernel_runs_once_per_observation_on_a_fresh_table(monkeypatch: pytest.MonkeyPatch,
                                                                     overrides: dict) -> None:  # fmt: skip
    env = env_on_a_new_map(**overrides)
    assert env.observer.table is not None and not env.observer.table.filled.any()
    paths, rivals = counting(monkeypatch, "stop_features"), counting(monkeypatch, "stop_rivals")
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    for step in range(1, 5):  # the third request is released at step 2: its stops are new then
        env.step(rng.integers(0, 16, size=(1, 2)))
        assert paths == [True] * (step + 1) and rivals == [True] * (step + 1)


def test_prepare_fills_the_rows_of_every_existing_stop_before_the_kernels() -> None:
    env = env_on_a_new_map()
    state = env.sim.reset(0)
    stops = next(c for c in env.observer.components if isinstance(c, StopsComponent))
    E, A, P = state.num_envs, state.num_taxis, state.pax_exists.shape[1]
    args = (state, env.world.arrays, env.observer.table.arrays, np.empty((E, A, P, 3), np.float32),
            np.empty((E, A, P, 16), np.int8))  # fmt: skip
    assert not stop_kernels.stop_features(*args)  # a fresh table: the kernel meets a missing row
    stops.prepare(state)
    assert stop_kernels.stop_features(*args)


def test_a_kernel_that_meets_a_missing_row_raises_naming_the_bug(monkeypatch: pytest.MonkeyPatch) -> None:
    env = env_on_a_new_map()
    for component in env.observer.components:
        monkeypatch.setattr(component, "prepare", lambda state: None)
    with pytest.raises(RuntimeError, match="did not compute: a bug"):
        env.reset(seed=0)


def test_prepare_computes_nothing_when_every_stop_has_its_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    env = env_on_a_new_map()
    env.reset(seed=0)  # its prepare filled the rows of every stop
    table = env.observer.table
    assert table is not None
    ensured: list[int] = []
    monkeypatch.setattr(table, "ensure", lambda stops: ensured.append(len(stops)))
    env.observer.observe(env.state)
    assert ensured == []
    gone = table.arrays._replace(distance_m=np.full_like(table.distance_m, np.nan))
    monkeypatch.setattr(table, "arrays", gone)  # every row gone: the next prepare asks for them
    with pytest.raises(RuntimeError, match="a bug"):  # the stub computed nothing, so the kernel meets the gap
        env.observer.observe(env.state)
    assert len(ensured) == 1 and ensured[0] == 2 * int(env.state.pax_exists.sum())
