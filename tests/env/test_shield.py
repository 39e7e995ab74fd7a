"""The separation shield (docs/rules.md "Separation shield") on drawn scenes against hand computations, and a seeded
fuzz of fleet episodes that never loses separation under it.

Scenes are on a 1,000 m open map, 100 m steps, the default 50 m separation. A move of heading k ends at
``p + 100 (cos 22.5°k, sin 22.5°k)``; two ends one heading apart (22.5°) from one point are 2 * 100 * sin 11.25° =
39.0 m apart, two headings apart (45°) 76.5 m, so a taxi turned aside from a shared end turns by 45°.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import Request, RewardConfig
from uamfleet.sim import motion
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.presets import make_config
from uamfleet.rollout import fly
from uamfleet.sim.world import World

OPEN_10 = "\n".join(["." * 10] * 10)
E, NE, N, W, S = 0, 2, 4, 8, 12
FAR_REQUEST = (Request(0, (50.0, 950.0), (950.0, 950.0)),)  # nobody reaches it in one step


def end(p: tuple[float, float], k: int) -> np.ndarray:
    return np.asarray(p) + 100.0 * np.array([math.cos(math.pi * k / 8), math.sin(math.pi * k / 8)])


def shield(pos, requested, free_seats=None, allowed=None, stayed=None):
    """motion.shield_headings on one env of drawn positions: the headings flown (-1: stays)."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    world = World(small_config(OPEN_10, starts_m=tuple(map(tuple, pos))))
    flown = np.empty(n, np.int64)
    motion.shield_headings(
        pos,
        np.asarray(free_seats if free_seats is not None else [2] * n, np.int64),
        np.asarray(stayed if stayed is not None else [0] * n, np.int64),
        np.ones((n, 16), bool) if allowed is None else allowed,
        np.asarray(requested, np.int64),
        world.arrays,
        flown,
    )
    return flown.tolist()


def min_gap(pos, flown) -> float:
    """Smallest distance between any two taxis over the slot, each flying its heading (or staying) at constant
    speed, sampled at 1,001 instants: an independent check of the closest-approach rule."""
    pos = np.asarray(pos, dtype=float)
    ends = np.array([end(p, k) if k >= 0 else p for p, k in zip(pos, flown, strict=True)])
    t = np.linspace(0.0, 1.0, 1001)[:, None, None]
    at = pos[None] + t * (ends - pos)[None]  # [T, A, 2]
    d = np.linalg.norm(at[:, :, None] - at[:, None, :], axis=-1)
    d[:, np.arange(len(pos)), np.arange(len(pos))] = np.inf
    return float(d.min())


def test_head_on_the_second_taxi_turns_aside_by_45_degrees():
    # 200 m apart, both asking for the point between them. Taxi 0 (first by index) keeps east: its end is 100 m
    # from taxi 1 staying. Taxi 1: west ends on taxi 0's end; 202.5° (heading 9) and 157.5° (7) end 39.0 m from
    # it; 225° (heading 10) ends at (529.3, 429.3), 76.5 m from it, the closest approach being at the end.
    pos = [(400.0, 500.0), (600.0, 500.0)]
    assert shield(pos, [E, W]) == [E, 10]
    assert min_gap(pos, [E, 10]) == pytest.approx(76.54, abs=0.01)


def test_taxis_one_step_apart_flying_at_each_other_do_not_swap_places_through_each_other():
    # 100 m apart: east and west would swap them, 100 m apart at both ends but meeting half-way. Taxi 0: east
    # ends on taxi 1, 22.5° and 337.5° end 39.0 m from it; 45° ends 76.5 m from it, closest 70.7 m at t = 0.71.
    # Taxi 1: west ends 100 m from taxi 0's end but comes within 38.3 m of it at t = 0.5, and taxi 0 was turned
    # aside: taxi 1 yields (hovers) and leaves taxi 0 the way round it.
    pos = [(450.0, 500.0), (550.0, 500.0)]
    assert min_gap(pos, [E, W]) == pytest.approx(0.0, abs=0.2)  # what the moves asked for would do
    assert shield(pos, [E, W]) == [NE, -1]
    assert min_gap(pos, [NE, -1]) == pytest.approx(70.7, abs=0.1)
    # Had taxi 1 stayed in place a step before (say it yielded), it goes first: its west move is turned to 225°
    # (heading 10) by the same geometry mirrored, and taxi 0, whose east move conflicts with it, yields.
    assert shield(pos, [E, W], stayed=[0, 1]) == [-1, 10]


def test_crossing_the_taxi_with_more_riders_keeps_its_heading():
    # Taxi 0 flies east and taxi 1 north onto one point (500, 500). Equal loads: taxi 0 (lower index) keeps east;
    # taxi 1's 112.5° and 67.5° end 39.0 m from it, 135° (heading 6) ends 76.5 m away (closest 54.1 m at t = 0.71).
    pos = [(400.0, 500.0), (500.0, 400.0)]
    assert shield(pos, [E, N]) == [E, 6]
    assert min_gap(pos, [E, 6]) == pytest.approx(54.1, abs=0.1)
    # Taxi 1 carries a rider (one free seat of two): it goes first and keeps north; taxi 0 turns to 45°.
    assert shield(pos, [E, N], free_seats=[2, 1]) == [NE, N]
    assert min_gap(pos, [NE, N]) == pytest.approx(76.5, abs=0.1)


def test_three_taxis_converging_on_one_stop():
    # West, south and east of the stop (500, 500), 100 m away, each asking for it. Taxi 0 keeps east. Taxi 1:
    # 225° would end 41.4 m from taxi 2 (still at (500, 400)); 135° (heading 6) ends at (529.3, 570.7). Taxi 2:
    # 112.5° / 67.5° end 39.0 m from taxi 0's end, 135° ends at (429.3, 470.7). Both end 76.5 m from the stop,
    # inside the 100 m pick-up radius.
    pos = [(400.0, 500.0), (600.0, 500.0), (500.0, 400.0)]
    flown = shield(pos, [E, W, N])
    assert flown == [E, 6, 6]
    assert min_gap(pos, flown) >= 50.0
    ends = np.array([end(p, k) for p, k in zip(pos, flown, strict=True)])
    np.testing.assert_allclose(np.linalg.norm(ends - [500.0, 500.0], axis=-1), [0.0, 76.54, 76.54], atol=0.01)

    # The same scene in the env: taxi 0 boards the passenger waiting at the stop; nobody loses separation.
    cfg = small_config(
        OPEN_10, starts_m=tuple(pos), separation="shield", requests=(Request(0, (500.0, 500.0), (500.0, 900.0)),)
    )
    env = VectorEnv(cfg)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[E, W, N]]))
    ev = info["events"]
    assert ev.heading_flown[0].tolist() == [E, 6, 6]
    assert ev.shield_intervened[0].tolist() == [False, True, True]
    assert not ev.hovered.any() and not ev.separation_violation.any() and ev.moved.all()
    assert ev.picked_up[0, 0] and env.state.pax_taxi[0, 0] == 0


RING = [(500.0 + 100.0 * math.cos(math.pi * j / 4), 500.0 + 100.0 * math.sin(math.pi * j / 4)) for j in range(8)]


def test_a_taxi_boxed_in_hovers():
    # Taxi 0 at (500, 500) inside a ring of 8 taxis 100 m away, 45° apart (76.5 m from each other): every
    # heading of taxi 0 ends 0 or 39.0 m from a ring taxi, so it hovers; the ring taxis fly outward.
    pos = [(500.0, 500.0), *RING]
    outward = [2 * j for j in range(8)]
    assert shield(pos, [E, *outward]) == [-1, *outward]

    weights = RewardConfig(shield=-7.0, hover=-3.0)
    cfg = small_config(OPEN_10, starts_m=tuple(pos), separation="shield", reward=weights, requests=FAR_REQUEST)
    env = VectorEnv(cfg)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[E, *outward]]))
    ev = info["events"]
    assert ev.hovered[0].tolist() == [True] + [False] * 8
    assert ev.shield_intervened[0].tolist() == [True] + [False] * 8
    assert ev.heading_flown[0, 0] == -1 and not ev.moved[0, 0] and not ev.blocked[0, 0]
    np.testing.assert_array_equal(env.state.pos_m[0, 0], [500.0, 500.0])
    assert env.state.distance_m[0, 0] == 0.0 and env.state.t[0] == 1  # time passes, no distance flown
    terms = dict(zip(uamfleet.REWARD_TERMS, info["reward_terms"][0, 0], strict=True))
    assert (terms["shield"], terms["hover"], terms["blocked"]) == (-7.0, -3.0, 0.0)
    assert info["reward_terms"][0, 1:, uamfleet.REWARD_TERMS.index("shield")].tolist() == [0.0] * 8


def test_a_move_that_is_not_allowed_stays_a_blocked_move():
    # East of (150, 150) is a bad block: blocked (stays, blocked penalty) as without the shield; not an intervention.
    wall = ".....\n.....\n.....\n..#..\n....."
    cfg = small_config(wall, starts_m=((150.0, 150.0), (450.0, 450.0)), separation="shield")
    env = VectorEnv(cfg)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[E, S]]))
    ev = info["events"]
    assert ev.blocked[0].tolist() == [True, False] and ev.heading_flown[0].tolist() == [-1, S]
    assert not ev.shield_intervened.any() and not ev.hovered.any()


def test_taxis_sharing_a_start_fan_out_in_the_first_step():
    # Four taxis at one point, all asking east. Without the shield all four end on one point; with it taxi 1 turns
    # to 45° (22.5° ends 39.0 m from taxi 0's end), taxi 2 to 315°, taxi 3 to 90° (67.5° and 292.5° end 39.0 m
    # from taxis 1 and 2): every pair ends at least 76.5 m apart.
    starts = ((500.0, 500.0),) * 4
    for separation, flown, violations in (("none", [E] * 4, 4), ("shield", [E, NE, 14, N], 0)):
        env = VectorEnv(small_config(OPEN_10, starts_m=starts, separation=separation, requests=FAR_REQUEST))
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.full((1, 4), E))
        assert info["events"].heading_flown[0].tolist() == flown
        assert info["events"].separation_violation.sum() == violations


def test_bad_separation_mode_is_named_with_the_fix():
    with pytest.raises(ValueError, match=r"separation='on' is unknown; use 'shield' .* or 'none'"):
        small_config(separation="on")


def test_fleet_presets_fly_with_the_shield_and_the_paper_scenarios_without():
    assert make_config("berlin_fleet").separation == "shield"
    assert make_config("detroit3gpp_fleet", num_taxis=2).separation == "shield"
    assert make_config("berlin_p4").separation == "none" and make_config("berlin_random").separation == "none"


def _herding_actions(env: VectorEnv, rng: np.random.Generator) -> np.ndarray:
    """Every taxi heads for the map's centre 3 times in 4 (the allowed heading nearest that bearing), else a random
    action (a heading, or the hover where the config has it): crowds that lose separation often without a shield."""
    s = env.state
    centre = env.world.side_m / 2
    bearing = np.arctan2(centre - s.pos_m[..., 1], centre - s.pos_m[..., 0])  # [E, A]
    k = np.round(bearing / (np.pi / 8)).astype(np.int64) % 16
    return np.where(rng.random(k.shape) < 0.75, k, rng.integers(0, env.cfg.num_actions, k.shape))


@pytest.mark.parametrize("num_taxis", [2, 4, 8])
def test_seeded_fuzz_of_fleet_episodes_never_loses_separation_under_the_shield(num_taxis):
    # berlin_fleet without the stop features (their path table is what costs time, not the shield), 4 envs x 150
    # steps of herding actions, hovers among them; the same actions' kind without the shield loses separation (so
    # the test can fail).
    counts = {}
    for separation in ("none", "shield"):
        cfg = make_config(
            "berlin_fleet", num_taxis=num_taxis, stop_features=False, stop_claims=False, separation=separation
        )
        env = VectorEnv(cfg, num_envs=4)
        env.reset(seed=21)
        rng = np.random.default_rng(num_taxis)
        violations = interventions = 0
        for _ in range(150):
            _, _, _, _, info = env.step(_herding_actions(env, rng))
            ev = info["events"]
            violations += int(ev.separation_violation.sum())
            interventions += int(ev.shield_intervened.sum())
            chosen = ev.actions == 16
            assert not (ev.hovered & ev.moved).any() and not (chosen & ev.shield_intervened).any()
            np.testing.assert_array_equal(ev.hovered & ~ev.shield_intervened, chosen)  # else the shield's hovers
        counts[separation] = (violations, interventions)
    assert counts["none"][0] > 0 and counts["none"][1] == 0
    assert counts["shield"][0] == 0 and counts["shield"][1] > 0


def _rollout_digest(scenario: str, steps: int, **overrides) -> str:
    """sha256 (first 16 hex digits) of 2 envs' positions, move / blocked / boarding / separation events, rewards,
    observed passengers, others and masks and distances over ``steps`` seeded random steps."""
    env = VectorEnv(make_config(scenario, **overrides), num_envs=2)
    obs, _ = env.reset(seed=7)
    rng = np.random.default_rng(3)
    h = hashlib.sha256()
    for _ in range(steps):
        obs, rew, _, _, info = env.step(rng.integers(0, 16, size=(2, env.num_taxis)))
        ev = info["events"]
        for arr in (ev.pos_m, ev.moved, ev.blocked, ev.picked_up, ev.dropped_off, ev.separation_violation, rew,
                    obs["passengers"], obs["others"], obs["action_mask"], env.state.distance_m):  # fmt: skip
            h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()[:16]


def test_no_shield_flies_bit_for_bit_as_before_the_shield():
    # Digests of the same code at commit 25892b5, the last one before the shield: the paper's Berlin P4 and four taxis
    # sharing a start on Berlin random demand (they lose separation; nothing may change).
    assert _rollout_digest("berlin_p4", 120) == "75d8743856fda2a8"
    assert _rollout_digest("berlin_random", 120, num_taxis=4, starts_m=((2600.0, 1500.0),) * 4) == "47e9857c4c0715a7"


def test_metrics_count_interventions_and_hovers_of_an_episode():
    # The boxed scene flown for 3 steps with the same headings: taxi 0 hovers in step 1 only (the ring has flown
    # outward by then); nobody is delivered, so the whole episode counts.
    pos = [(500.0, 500.0), *RING]
    cfg = small_config(OPEN_10, starts_m=tuple(pos), separation="shield", requests=FAR_REQUEST, time_limit_steps=3)
    actions = np.array([[E, *(2 * j for j in range(8))]])
    traj = fly(cfg, lambda obs: actions)
    m = episode_metrics(traj, cfg.radio)
    assert (m.steps, m.shield_interventions, m.hovers, m.separation_violations) == (3, 1, 1, 0)
    assert m.hover_actions == 0  # the shield's hover, not a chosen one
    assert m.interventions_per_taxi_h == pytest.approx(1 / (9 * 3 * 3.0 / 3600))  # 9 taxis x 3 steps of 3 s
    assert m.td_m == 26 * 100.0  # 8 ring taxis x 3 steps + taxi 0's 2 steps


def _toward(goals: np.ndarray):
    """A policy for drawn scenes: every taxi asks for the heading nearest the bearing to its goal, and hovers (the
    hover action) once within 50 m of it."""

    def act(env: VectorEnv) -> np.ndarray:
        pos = env.state.pos_m[0]
        delta = goals - pos
        k = np.round(np.arctan2(delta[:, 1], delta[:, 0]) / (np.pi / 8)).astype(np.int64) % 16
        return np.where(np.linalg.norm(delta, axis=-1) < 50.0, 16, k)[None]

    return act


def test_two_taxis_that_must_pass_each_other_do_not_shadow_each_other():
    # The scene of the deadlocked 8 x 48 episodes before the yield rule (batch_assignment, Berlin test seed
    # 2000005): two taxis 53 m apart, each bound for a point beyond the other. Taxi 0's move through taxi 1 is
    # turned aside (south-east, heading 14: 225° and the like end too close to taxi 1); taxi 1's move then conflicts
    # with taxi 0's turned move and yields (hovers) instead of turning beside it. Without that rule both turned the
    # same way every step (south, then north, ...) until the time limit. Both arrive; nobody loses separation.
    starts = ((447.0, 500.0), (500.0, 502.0))
    goals = np.array([[900.0, 480.0], [100.0, 520.0]])
    cfg = small_config(OPEN_10, starts_m=starts, separation="shield", hover_action=True, requests=FAR_REQUEST)
    env = VectorEnv(cfg)
    env.reset(seed=0)
    act = _toward(goals)
    first = None
    for _ in range(12):
        _, _, _, _, info = env.step(act(env))
        ev = info["events"]
        assert not ev.separation_violation.any()
        first = ev.heading_flown[0].tolist() if first is None else first
    assert first[1] == -1 and first[0] != -1  # one taxi turned aside, the other yielded
    assert (np.linalg.norm(env.state.pos_m[0] - goals, axis=-1) < 50.0).all(), env.state.pos_m[0]
