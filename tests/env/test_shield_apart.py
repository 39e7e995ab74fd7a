"""The separation shield parts taxis that are already in conflict (docs/rules.md "Separation shield" rule 7, and
"Starts"), and refuses fleets that could never be separated: drawn scenes against hand computations, the
refusals, and a seeded fuzz over start configurations flown by the fleet dispatchers.

Scenes are on drawn maps of 100 m blocks, 100 m steps. A move of heading k ends at
``p + 100 (cos 22.5°k, sin 22.5°k)``; two moves from one point with headings d apart end ``200 sin(11.25° d)`` m
apart: 39.0 m for one heading, 76.5 m for two, 200 m for opposite headings.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import small_config

from uamfleet.checks import ConfigError
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.policies import make_flown
from uamfleet.presets import make_config
from uamfleet.rollout import run_episode
from uamfleet.sim import motion
from uamfleet.sim.generator import InfeasibleInstanceError
from uamfleet.sim.world import World
from uamfleet.types import HOVER_ACTION

OPEN_10 = "\n".join(["." * 10] * 10)
E, NE, N, W, SW, S = 0, 2, 4, 8, 10, 12
P = (500.0, 500.0)
FAR_REQUEST = (Request(0, (50.0, 950.0), (950.0, 950.0)),)  # nobody reaches it in one step


def shield(pos, requested, min_separation_m, allowed=None):
    """motion.shield_headings on one env of drawn positions: the headings flown (-1: stays)."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    world = World(small_config(OPEN_10, starts_m=tuple(map(tuple, pos)), min_separation_m=min_separation_m))
    flown = np.empty(n, np.int64)
    motion.shield_headings(
        pos, np.full(n, 2, np.int64), np.zeros(n, np.int64), np.ones((n, 16), bool) if allowed is None else allowed,
        np.asarray(requested, np.int64), world.arrays, flown,
    )  # fmt: skip
    return flown.tolist()


def test_two_taxis_sharing_a_start_part_when_the_separation_is_above_a_step():
    # 150 m separation, 100 m steps: every move from the shared start ends 100 m from the other taxi staying, so
    # no move is clear by rules 3-5 and both would hover for ever. Rule 7: taxi 0 (first) moves apart; every
    # heading ends 100 m from taxi 1, so it keeps the one asked for (east; east too for a hover). Taxi 1 is then
    # 100 m from taxi 0's end, still in conflict: any other heading takes them apart, and west ends farthest
    # from taxi 0's end (200 m, separated).
    for requested in ([E, E], [HOVER_ACTION, HOVER_ACTION], [N, HOVER_ACTION]):
        first = requested[0] if requested[0] != HOVER_ACTION else E
        assert shield([P, P], requested, 150.0) == [first, (first + 8) % 16]


def test_a_taxi_in_conflict_moves_apart_only_while_staying_would_keep_the_conflict():
    # Two taxis on one point asking to hover, default 50 m: taxi 0 moves east (all headings end 100 m from taxi 1,
    # the first in angle from east is kept); taxi 1, 100 m from taxi 0's end, is no longer in conflict and stays.
    # A third taxi 300 m away is in nobody's way and keeps its hover.
    far = (800.0, 500.0)
    assert shield([P, P, far], [HOVER_ACTION] * 3, 50.0) == [E, -1, -1]
    # Separated taxis are never moved: staying is clear (rules 3-6 alone).
    assert shield([P, (560.0, 500.0)], [HOVER_ACTION] * 2, 50.0) == [-1, -1]


def test_a_blocked_taxi_in_conflict_moves_apart_on_an_allowed_heading():
    # Both taxis on one point may fly only north or south (a drawn mask) and ask for east: blocked, they would
    # stay. At 150 m taxi 0 moves apart on north (the first allowed heading in angle from east, all ending 100 m
    # from taxi 1) and taxi 1 on south (north would end on taxi 0: not apart; south ends 200 m from it).
    allowed = np.zeros((2, 16), bool)
    allowed[:, [N, S]] = True
    assert shield([P, P], [E, E], 150.0, allowed) == [N, S]


def test_in_the_env_parted_taxis_are_shield_interventions_not_hovers():
    # The blocked case in the env: the shared start (150, 250) has a no-fly block (x and y 200-300 m) east of it.
    # East, 22.5° and 337.5° end in it; taxi 0 moves apart on 45° (NE), taxi 1 on 225° (SW, 200 m from taxi 0's
    # end). Both asked for a move that is not allowed: blocked (its penalty), moved by the shield (an
    # intervention), not a hover.
    wall = ".....\n.....\n..#..\n.....\n....."
    cfg = small_config(
        wall, starts_m=((150.0, 250.0),) * 2, separation="shield", min_separation_m=150.0,
        requests=(Request(0, (50.0, 450.0), (450.0, 450.0)),), hover_action=True,
    )  # fmt: skip
    env = VectorEnv(cfg)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[E, E]]))
    ev = info["events"]
    assert ev.heading_flown[0].tolist() == [NE, SW]
    assert ev.blocked[0].tolist() == [True, True] and ev.moved[0].tolist() == [True, True]
    assert ev.shield_intervened[0].tolist() == [True, True] and not ev.hovered.any()
    assert not ev.separation_violation.any()
    d = 100.0 / math.sqrt(2.0)
    np.testing.assert_allclose(env.state.pos_m[0], [[150.0 + d, 250.0 + d], [150.0 - d, 250.0 - d]])

    # Asking to hover on the shared start: parted the same way (east first for a hover), as interventions.
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[HOVER_ACTION, HOVER_ACTION]]))
    ev = info["events"]
    assert ev.moved[0].all() and ev.shield_intervened[0].all() and not ev.hovered.any()
    assert not ev.separation_violation.any()


def test_eight_hovering_taxis_on_one_point_part_and_stay_parted():
    # Eight taxis sharing a start, all asking to hover every step (default 50 m): the shield spreads them and from
    # then on nobody is in conflict (before rule 7 they hovered on the point, all in violation, every step).
    cfg = small_config(OPEN_10, starts_m=(P,) * 8, separation="shield", hover_action=True, requests=FAR_REQUEST)
    env = VectorEnv(cfg)
    env.reset(seed=0)
    violations = []
    for _ in range(10):
        _, _, _, _, info = env.step(np.full((1, 8), HOVER_ACTION))
        violations.append(int(info["events"].separation_violation.sum()))
    parted = violations.index(0)
    assert parted <= 3 and not any(violations[parted:]), violations
    pos = env.state.pos_m[0]
    gaps = np.linalg.norm(pos[:, None] - pos[None], axis=-1)[np.triu_indices(8, 1)]
    assert gaps.min() >= 50.0


# ---- refusals -------------------------------------------------------------------------------------------------


def test_a_separation_the_map_cannot_hold_is_refused_at_config_time():
    # The 1,000 m map holds two taxis 1,414 m apart (opposite corners, 1,414.2 m), never three (Oler's bound:
    # 2/sqrt(3) * 1000^2 / 1414^2 + 4000 / (2 * 1414) + 1 = 2.99), and no pair 1,500 m apart.
    two, three = ((150.0, 150.0), (850.0, 850.0)), ((150.0, 150.0), (850.0, 850.0), (150.0, 850.0))
    small_config(OPEN_10, starts_m=two, separation="shield", min_separation_m=1414.0)
    with pytest.raises(ConfigError, match=r"min_separation_m=1414 leaves room for at most 2 taxi\(s\) .* num_taxis=3"):
        small_config(OPEN_10, starts_m=three, separation="shield", min_separation_m=1414.0)
    with pytest.raises(ConfigError, match=r"at most 1 taxi\(s\) .* map's diagonal, 1414 m\), fly fewer taxis, or use"):
        small_config(OPEN_10, starts_m=two, separation="shield", min_separation_m=1500.0)
    small_config(OPEN_10, starts_m=two, separation="none", min_separation_m=1500.0)  # only recorded: no refusal
    with pytest.raises(ConfigError, match=r"min_separation_m=2000 leaves room for at most 7 .* num_taxis=8"):
        make_config("berlin_fleet", num_taxis=8, min_separation_m=2000.0)  # 3,260 m map: 2.9 + 3.3 + 1 = 7.2


# A 200 m x 100 m flyable pocket (x 200-400 m, y 200-300 m) and an open area north of y = 600 m.
POCKET = "\n".join(["." * 10] * 4 + ["#" * 10] * 3 + ["##..######"] + ["#" * 10] * 2)


def test_taxis_in_a_flyable_pocket_too_small_to_part_are_refused_when_the_env_is_built():
    # Taxis 0 and 2 start in the pocket, whose farthest points are 223.6 m apart (its diagonal): never 250 m apart.
    starts = ((250.0, 250.0), (450.0, 850.0), (350.0, 250.0))
    requests = (Request(0, (450.0, 750.0), (850.0, 750.0)),)
    cfg = small_config(POCKET, starts_m=starts, requests=requests, separation="shield", min_separation_m=250.0)
    with pytest.raises(
        InfeasibleInstanceError,
        match=r"^taxis \[0, 2\] \(starts from \(250.0, 250.0\)\) cannot all be min_separation_m=250 m apart in one "
        r"flyable area of drawn .* room for at most 1 taxi\(s\) .*separation='none'\.$",
    ):
        VectorEnv(cfg)
    VectorEnv(cfg.replace(min_separation_m=200.0))  # may fit (the pocket's ends): not refused
    VectorEnv(cfg.replace(separation="none"))

    # Random starts are drawn in the largest flyable area: only the pocket here, too small for two taxis.
    pocket_only = "\n".join(["#" * 10] * 7 + ["##..######"] + ["#" * 10] * 2)
    cfg = small_config(pocket_only, starts_m=None, num_taxis=2, requests=None, separation="shield",
                       min_separation_m=250.0)  # fmt: skip
    with pytest.raises(InfeasibleInstanceError, match=r"^the 2 taxis \(random starts\) cannot all be"):
        VectorEnv(cfg)


# ---- a seeded fuzz over start configurations --------------------------------------------------------------------

SEPARATIONS = (30.0, 50.0, 75.0, 100.0, 120.0, 1500.0)  # 1,500 m: more than the map's diagonal, refused
POLICIES = ("greedy", "batch_assignment", "insertion")
SHAPES = ("coincident", "ring", "box")


def _fuzz_config(seed: int):
    """Seed -> (config kwargs, policy name): 2-8 taxis on the open 1,000 m map starting on one point, on a ring
    narrower than the separation, or drawn in a box narrower than it (so some pairs start in conflict), one
    request per taxi between block centres released in the first 20 steps, with or without the hover action."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 9))
    sep = float(rng.choice(SEPARATIONS))
    shape = SHAPES[seed % 3]
    centre = rng.uniform(250.0, 750.0, 2)
    width = rng.uniform(0.0, min(sep, 200.0))
    if shape == "coincident":
        starts = np.repeat(centre[None], n, axis=0)
    elif shape == "ring":
        angles = 2 * np.pi * np.arange(n) / n + rng.uniform(0, 2 * np.pi)
        starts = centre + width / 2 * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    else:
        starts = centre + rng.uniform(-width / 2, width / 2, (n, 2))
    sites = (np.arange(10) + 0.5) * 100.0
    requests = []
    for _ in range(n):
        origin = rng.choice(sites, 2)
        destination = origin
        while (destination == origin).all():
            destination = rng.choice(sites, 2)
        requests.append(Request(int(rng.integers(0, 20)), tuple(origin), tuple(destination)))
    kwargs = dict(
        starts_m=tuple(map(tuple, starts.round(3))), requests=tuple(requests), separation="shield",
        min_separation_m=sep, hover_action=bool(rng.integers(2)), time_limit_steps=300,
    )  # fmt: skip
    return kwargs, POLICIES[seed % len(POLICIES)]


def _fly_fuzz_case(seed: int) -> None:
    kwargs, policy = _fuzz_config(seed)
    n, sep = len(kwargs["starts_m"]), kwargs["min_separation_m"]
    if sep > 1000.0 * math.sqrt(2.0):
        with pytest.raises(ConfigError, match=r"leaves room for at most 1 taxi"):
            small_config(OPEN_10, **kwargs)
        return
    env = VectorEnv(small_config(OPEN_10, **kwargs), num_envs=1, autoreset=False)
    traj = run_episode(env, make_flown(policy, num_taxis=n), seed=0)
    violating = traj.stacked("separation_violation").reshape(len(traj.events), -1).any(axis=-1)  # per step
    parted = int(np.argmin(violating)) if not violating.all() else len(violating)
    label = f"seed {seed}: {n} taxis, {sep:g} m, {policy}, violations per step {violating.astype(int).tolist()}"
    assert parted <= 10, label  # everyone apart within 10 steps ...
    assert not violating[parted:].any(), label  # ... and never in conflict again
    assert int(traj.stacked("dropped_off").sum()) == n, label  # everyone delivered


def test_seeded_fuzz_of_start_configurations_parts_everyone_and_delivers_everyone():
    for seed in range(18):  # 1-2 s: 6 coincident, 6 rings, 6 boxes; 5 refused (1,500 m), 3 at 120 m
        _fly_fuzz_case(seed)


@pytest.mark.slow
def test_seeded_fuzz_of_start_configurations_long():
    for seed in range(18, 618):
        _fly_fuzz_case(seed)


def _greedy_packing(points: np.ndarray, min_separation_m: float) -> int:
    """How many of ``points`` a greedy pass keeps pairwise at least ``min_separation_m`` apart: a packing that
    exists, so a true bound on the room is never below it."""
    kept: list[np.ndarray] = []
    for p in points:
        if all(np.linalg.norm(p - q) >= min_separation_m for q in kept):
            kept.append(p)
    return len(kept)


def test_the_room_bounds_are_never_below_a_packing_that_exists():
    # A refusal must be certain: on random drawn maps, the room of the flyable blocks (corners and centres of the
    # blocks as candidate points) is at least what a greedy packing places, and the square's bound at least a
    # square lattice s apart ((floor(L / s) + 1)^2 points). Hand values on the 1,000 m square: 1,414 m fits two
    # (opposite corners), 1,500 m one.
    from uamfleet.config import separation_room_bound
    from uamfleet.sim.generator import _flyable_rects, separation_room

    assert (separation_room_bound(1000.0, 1000.0, 1414.0), separation_room_bound(1000.0, 1000.0, 1500.0)) == (2, 1)
    rng = np.random.default_rng(5)
    for trial in range(12):
        art = "\n".join("".join(rng.choice([".", "#"], p=[0.6, 0.4], size=10)) for _ in range(10))
        world = World(small_config(art, starts_m=None, requests=None))
        rects = _flyable_rects(world)
        candidates = np.concatenate([rects[:, :2], rects[:, 2:], (rects[:, :2] + rects[:, 2:]) / 2])
        for sep in (60.0, 100.0, 141.0, 150.0, 250.0, 400.0, 900.0):
            sep *= 1.0 + rng.uniform(0, 0.1)
            assert separation_room(rects, sep) >= _greedy_packing(rng.permutation(candidates), sep), (trial, sep)
            side = math.floor(1000.0 / sep) + 1
            assert separation_room_bound(1000.0, 1000.0, sep) >= side * side
