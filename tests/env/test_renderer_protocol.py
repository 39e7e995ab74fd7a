"""The PettingZoo face draws through an injected Renderer (layers point down: env never imports viz)."""

from __future__ import annotations

import numpy as np
import pytest

import uamfleet
from uamfleet.env.parallel_env import UAMFleetParallelEnv


class Recording:
    def __init__(self, mode: str) -> None:
        self.mode, self.calls, self.closed = mode, [], False

    def render(self, env: UAMFleetParallelEnv) -> np.ndarray:
        self.calls.append(int(env.core.state.t[0]))
        return np.full((2, 2, 3), len(self.calls), dtype=np.uint8)

    def close(self) -> None:
        self.closed = True


def test_an_injected_renderer_is_made_once_and_closed() -> None:
    made: list[Recording] = []

    def factory(mode: str, env: UAMFleetParallelEnv) -> Recording:
        made.append(Recording(mode))
        return made[-1]

    env = UAMFleetParallelEnv(uamfleet.make_config("berlin_p4"), render_mode="rgb_array", renderer=factory)
    obs, _ = env.reset(seed=0)
    assert made == []  # nothing is drawn before the first render()
    first = env.render()
    env.step({"uam_0": int(np.flatnonzero(obs["uam_0"]["action_mask"])[0])})
    second = env.render()
    assert len(made) == 1 and made[0].mode == "rgb_array" and made[0].calls == [0, 1]
    assert int(first[0, 0, 0]) == 1 and int(second[0, 0, 0]) == 2
    assert env.trails_m.shape == (1, 2, 2)  # start and one step, kept because a render mode is set
    env.close()
    assert made[0].closed


def test_without_a_renderer_a_render_mode_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(UAMFleetParallelEnv, "default_renderer", None)
    with pytest.raises(ValueError, match="needs a renderer"):
        UAMFleetParallelEnv(uamfleet.make_config("berlin_p4"), render_mode="rgb_array")
    assert UAMFleetParallelEnv(uamfleet.make_config("berlin_p4")).render() is None  # no mode, nothing drawn


def test_import_uamfleet_registers_the_viz_renderer() -> None:
    assert UAMFleetParallelEnv.default_renderer is not None
