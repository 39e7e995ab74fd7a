"""The pre-typed kernel entry (uamfleet.sim.pretyped): the same results as numba's dispatcher, typed once per pair
of NamedTuples, and a fallback to the dispatcher for actions of another memory layout."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

import uamfleet
from uamfleet.env.vector_env import VectorEnv
from uamfleet.sim import dynamics, motion
from uamfleet.sim.pretyped import PreTyped


class Pair(NamedTuple):
    a: np.ndarray
    b: np.ndarray


@njit(cache=False)
def _weighted(p: Pair, q: Pair, scale: float, out: np.ndarray) -> float:
    total = 0.0
    for i in range(p.a.shape[0]):
        out[i] = scale * (p.a[i] * q.b[i] + p.b[i])
        total += out[i]
    return total


class CountingKernel:
    """A stand-in for a numba dispatcher that counts how often it is asked to type and dispatch."""

    def __init__(self) -> None:
        self.dispatched, self.typed, self.entered = 0, 0, 0
        self.overloads = {("object", "object", "float"): type("Result", (), {"entry_point": self.entry})()}

    def __call__(self, *args: Any) -> str:
        self.dispatched += 1
        return "dispatched"

    def typeof_pyval(self, value: Any) -> str:
        self.typed += 1
        return type(value).__name__

    def entry(self, *args: Any) -> str:
        self.entered += 1
        return "entered"


def test_typed_once_per_pair_of_named_tuples() -> None:
    kernel = CountingKernel()
    call = PreTyped(kernel)
    state, world = object(), object()
    assert [call(state, world, 1.0) for _ in range(4)] == ["dispatched", "entered", "entered", "entered"]
    assert (kernel.dispatched, kernel.typed, kernel.entered) == (1, 3, 3)  # 3 arguments typed, once
    assert call(object(), world, 1.0) == "dispatched"  # another state: through the dispatcher again
    assert call(state, world, 1.0) == "dispatched"  # and back: looked up again, not assumed
    assert kernel.dispatched == 3 and kernel.typed == 9


def test_same_results_as_the_dispatcher() -> None:
    rng = np.random.default_rng(0)
    p, q = Pair(rng.random(5), rng.random(5)), Pair(rng.random(5), rng.random(5))
    expected_out = np.empty(5)
    expected = _weighted(p, q, 2.5, expected_out)
    call = PreTyped(_weighted)
    for _ in range(3):  # the first call dispatches, the others enter the machine code directly
        out = np.empty(5)
        assert call(p, q, 2.5, out) == expected
        np.testing.assert_array_equal(out, expected_out)
    np.testing.assert_array_equal(expected_out, 2.5 * (p.a * q.b + p.b))  # computed independently


def test_the_step_kernel_falls_back_for_actions_of_another_layout() -> None:
    """Two envs of one seed: one stepped with C-contiguous actions, the other alternately with C-contiguous
    actions (which its pre-typed kernel is compiled for) and a strided view of the same actions (which the machine
    code of C-contiguous arrays would misread): the same states."""
    cfg = uamfleet.make_config("berlin_random", num_taxis=3)
    plain, mixed = VectorEnv(cfg, num_envs=2), VectorEnv(cfg, num_envs=2)
    plain.reset(seed=3)
    mixed.reset(seed=3)
    rng = np.random.default_rng(1)
    for t in range(30):
        actions = rng.integers(0, 16, size=(2, 3))
        wide = np.full((2, 6), 15, np.int64)
        wide[:, ::2] = actions
        strided = wide[:, ::2]  # int64, not C-contiguous: every other element of wide
        assert not strided.flags.c_contiguous
        a = dynamics.step(plain.state, np.ascontiguousarray(actions), plain.world, plain._step_kernel)
        b = dynamics.step(mixed.state, strided if t % 2 else actions.copy(), mixed.world, mixed._step_kernel)
        np.testing.assert_array_equal(b.actions, actions)
        np.testing.assert_array_equal(a.pos_m, b.pos_m)
    for x, y in zip(plain.state, mixed.state, strict=True):
        np.testing.assert_array_equal(x, y)
    assert mixed._step_kernel._first is mixed.state  # the C-contiguous steps took the pre-typed path


def test_the_step_entry_is_the_dispatchers_compiled_code() -> None:
    env = VectorEnv(uamfleet.make_config("berlin_p4"), num_envs=1)
    env.reset(seed=0)
    env.step(np.zeros((1, 1), np.int64))
    kernel = env._step_kernel
    assert kernel.kernel is motion.step
    assert kernel._entry in [result.entry_point for result in motion.step.overloads.values()]
