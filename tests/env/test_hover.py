"""The hover action (``EnvConfig.hover_action``, docs/rules.md "Motion"): action 16 stays in place, always
allowed; off by default (the paper's scenarios keep 16 actions), on in the ``*_fleet`` presets; the dispatchers'
idle taxis hover with it instead of zig-zagging; the metrics count it."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import Request, RewardConfig
from uamfleet.env.parallel_env import UAMFleetParallelEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.policies import make_flown
from uamfleet.presets import make_config
from uamfleet.rollout import fly
from uamfleet.sim.dynamics import InvalidActionError
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS

OPEN_10 = "\n".join(["." * 10] * 10)
HOVER = 16


def test_the_hover_is_action_16_after_the_headings():
    assert HOVER_ACTION == NUM_HEADINGS == HOVER


@pytest.mark.parametrize("separation", ["none", "shield"])
def test_a_hover_stays_in_place_time_passes_no_distance_flown(separation):
    weights = RewardConfig(step=-2.0, hover=-0.5, shield=-7.0, blocked=-50.0)
    starts = ((150.0, 150.0), (550.0, 550.0))
    cfg = small_config(OPEN_10, starts_m=starts, hover_action=True, separation=separation, reward=weights)
    env = VectorEnv(cfg)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[HOVER, 0]]))  # taxi 0 hovers, taxi 1 flies east
    ev = info["events"]
    np.testing.assert_array_equal(env.state.pos_m[0], [[150.0, 150.0], [650.0, 550.0]])
    assert env.state.distance_m[0].tolist() == [0.0, 100.0] and env.state.t[0] == 1
    assert ev.hovered[0].tolist() == [True, False] and ev.moved[0].tolist() == [False, True]
    assert not ev.blocked.any() and not ev.shield_intervened.any()
    assert ev.heading_flown[0].tolist() == [-1, 0] and ev.actions[0].tolist() == [HOVER, 0]
    terms = dict(zip(uamfleet.REWARD_TERMS, info["reward_terms"][0, 0], strict=True))
    # a hover pays its time (the step term) and the hover weight; it is neither blocked nor a shield intervention
    assert (terms["step"], terms["hover"], terms["blocked"], terms["shield"]) == (-2.0, -0.5, 0.0, 0.0)
    np.testing.assert_array_equal(env.state.history_m[0, 0, 0], [150.0, 150.0])  # the history still shifts


def test_the_hover_is_refused_without_the_option_with_the_fix():
    env = VectorEnv(small_config(OPEN_10))
    env.reset(seed=0)
    with pytest.raises(InvalidActionError, match=r"action 16 of env 0, taxi 0 is outside 0..15.*hover_action=True"):
        env.step(np.array([[HOVER]]))
    hovering = VectorEnv(small_config(OPEN_10, hover_action=True))
    hovering.reset(seed=0)
    with pytest.raises(InvalidActionError, match=r"action 17 of env 0, taxi 0 is outside 0..16.*16: hover"):
        hovering.step(np.array([[17]]))


def test_the_action_space_grows_by_one_and_the_mask_does_not():
    plain, hovering = small_config(OPEN_10), small_config(OPEN_10, hover_action=True)
    assert (plain.num_actions, hovering.num_actions) == (16, 17)
    env = VectorEnv(hovering)
    assert env.single_action_space.n == 17
    assert env.single_observation_space["action_mask"].shape == (16,)  # a hover is always allowed: not in the mask
    zoo = UAMFleetParallelEnv(hovering)
    assert zoo.action_space("uam_0").n == 17
    zoo.reset(seed=0)
    zoo.step({"uam_0": HOVER})
    np.testing.assert_array_equal(zoo.core.state.pos_m[0, 0], [150.0, 150.0])
    plain_zoo = UAMFleetParallelEnv(plain)
    plain_zoo.reset(seed=0)
    with pytest.raises(InvalidActionError, match=r"outside 0\.\.15"):
        plain_zoo.step({"uam_0": HOVER})


def test_fleet_presets_have_the_hover_and_the_paper_scenarios_do_not():
    assert make_config("berlin_fleet").hover_action and make_config("detroit3gpp_fleet", num_taxis=2).hover_action
    assert not make_config("berlin_p4").hover_action and not make_config("berlin_random").hover_action
    with pytest.raises(ValueError, match=r"hover_action='yes' must be True or False"):
        small_config(hover_action="yes")


@pytest.mark.parametrize("name", ["greedy", "insertion", "batch_assignment"])
def test_an_idle_dispatcher_taxi_hovers_instead_of_zig_zagging(name):
    # One taxi at (150, 150); its only request (550, 150) -> (950, 150) is released at step 3 (seen at the call of
    # t = 3, which batch_assignment's period of 3 also dispatches). With the hover: calls t = 0, 1, 2 hover, then
    # three moves east put the taxi 100 m from the origin (pick-up at step 6: waited 3 steps of 3 s), four more
    # 100 m from the destination (delivered at step 10): 700 m flown. Without it the idle taxi flies a step away
    # and back about where it became idle: more distance, the same wait at best.
    request = (Request(3, (550.0, 150.0), (950.0, 150.0)),)
    flown = {}
    for hover in (True, False):
        cfg = small_config(OPEN_10, requests=request, hover_action=hover, separation="shield")
        traj = fly(cfg, make_flown(name, num_taxis=1))
        m = episode_metrics(traj, cfg.radio)
        flown[hover] = (m, traj.stacked("actions")[:3, 0].tolist())
    m, first = flown[True]
    assert first == [HOVER] * 3
    assert (m.td_m, m.awt_s, m.steps, m.hover_actions, m.hovers, m.pr_pct) == (700.0, 9.0, 10, 3, 3, 100.0)
    m_zig, first_zig = flown[False]
    assert HOVER not in first_zig and m_zig.hover_actions == 0 and m_zig.hovers == 0
    assert m_zig.td_m >= m.td_m + 200.0  # at least one step away and one back
    assert m_zig.awt_s >= m.awt_s


def test_metrics_count_chosen_and_shield_hovers_and_interventions_per_taxi_hour():
    # Two taxis far apart, 4 steps: taxi 0 hovers in steps 1 and 3 (chosen), taxi 1 flies east; nobody is
    # delivered, so the whole episode counts; no intervention.
    cfg = small_config(
        OPEN_10, starts_m=((150.0, 150.0), (150.0, 750.0)), hover_action=True, separation="shield",
        requests=(Request(0, (950.0, 950.0), (50.0, 950.0)),), time_limit_steps=4,
    )  # fmt: skip
    script = iter([[HOVER, 0], [0, 0], [HOVER, 0], [4, 0]])
    traj = fly(cfg, lambda obs: np.array([next(script)]))
    m = episode_metrics(traj, cfg.radio)
    assert (m.steps, m.hover_actions, m.hovers, m.shield_interventions, m.interventions_per_taxi_h) == (4, 2, 2, 0, 0.0)
    assert m.td_m == 6 * 100.0
