"""The stop features (``EnvConfig.stop_features``): per stop, the feasible-path distance and the heading that
makes most progress along it, against a Python recomputation from the same table and hand-checked drawn maps."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tests.conftest import drawn_map, small_config
from uamfleet.config import ConfigError, DemandConfig, Request
from uamfleet.observe import tours
from uamfleet.observe.moves import _progress_heading
from uamfleet.observe.stops import stop_features
from uamfleet.sim.motion import action_mask
from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.paths import table_for
from uamfleet.paths.distance_table import table_distance
from uamfleet.presets import make_config
from uamfleet.sim.generator import sample_requests
from uamfleet.sim.world import World
from uamfleet.types import NUM_HEADINGS, WAITING

# A wall at x = 300-400 m from y = 100 m to 500 m: from the west side, the stop on the east side is reached over the
# wall's north end (the gap at y = 500-700 m), never straight east and never round the south (there is no gap).
WALL = """
.......
.......
...#...
...#...
...#...
...#...
...#...
"""


def expected_heading(world: World, pos: np.ndarray, goal: np.ndarray, mask: np.ndarray) -> int:
    """Argmin over allowed headings of move + table distance left (the move alone when it ends in the radius)."""
    table = table_for(world)
    costs = []
    for h in range(NUM_HEADINGS):
        q = pos + world.moves_m[h]
        if not mask[h]:
            costs.append(np.inf)
        elif np.linalg.norm(q - goal) <= world.cfg.radius_m:
            costs.append(world.step_m)
        else:
            costs.append(world.step_m + float(table.distance(q, goal)))
    return int(np.argmin(costs))


def test_heading_goes_round_the_wall_and_matches_a_python_recomputation() -> None:
    cfg = small_config(
        WALL, starts_m=((150.0, 350.0),), requests=(Request(0, (550.0, 350.0), (650.0, 50.0)),), stop_features=True,
        time_limit_steps=40, patch_size=4,
    )  # fmt: skip
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=0)
    world, table = env.world, table_for(env.world)
    onehot = obs["stop_heading_mask"][0, 0, 0]
    assert onehot.sum() == 1
    heading = int(onehot.argmax())
    assert heading in (1, 2, 3), f"heading {heading}: the path goes north-east over the wall"
    pos, goal = env.state.pos_m[0, 0], np.array([550.0, 350.0])
    assert heading == expected_heading(world, pos, goal, env.state.action_mask[0, 0])
    side = world.side_m
    assert obs["stop_paths"][0, 0, 0, 0] == pytest.approx(float(table.distance(pos, goal)) / side, rel=1e-6)
    ride = float(table.distance(np.array([550.0, 350.0]), np.array([650.0, 50.0])))
    assert obs["stop_paths"][0, 0, 0, 1] == pytest.approx(ride / side, rel=1e-6)
    # the path round the wall is longer than the straight line (the wall is in the way)
    assert obs["stop_paths"][0, 0, 0, 0] * side > 400.0 + 100.0

    # Follow the marked heading: the taxi picks the passenger up and delivers her, never blocked.
    for _ in range(40):
        action = obs["stop_heading_mask"][0, 0].max(0).argmax()
        obs, _, terminated, _, info = env.step(np.array([[action]]))
        assert info["events"].moved.all()
        if terminated[0]:
            break
    assert terminated[0]


def test_rows_without_an_actionable_stop_are_zero() -> None:
    """Hidden rows, delivered rows and waiting rows of a full taxi have no stop: zero distance and no heading;
    the ride distance is still given for a visible row."""
    reqs = (
        Request(0, (150.0, 250.0), (450.0, 450.0)),  # picked up at the first step (taxi moves next to it)
        Request(0, (450.0, 50.0), (50.0, 450.0)),  # waits; the taxi has one seat
        Request(30, (250.0, 450.0), (50.0, 50.0)),  # hidden until step 30
    )
    cfg = small_config(starts_m=((150.0, 150.0),), requests=reqs, seats=1, stop_features=True, patch_size=4)
    env = VectorEnv(cfg, num_envs=1)
    env.reset(seed=0)
    obs, *_ = env.step(np.array([[4]]))  # heading 4 = north: onto passenger 0's origin
    assert env.state.pax_status[0, 0] == 2  # on board
    paths, heading = obs["stop_paths"][0, 0], obs["stop_heading_mask"][0, 0]
    assert heading[0].sum() == 1 and paths[0, 0] > 0  # her destination
    assert heading[1].sum() == 0 and paths[1, 0] == 0.0 and paths[1, 1] > 0  # waiting, but no free seat
    assert heading[2].sum() == 0 and np.all(paths[2] == 0.0)  # not released


def test_observation_space_and_kernel_fill_table_rows_on_demand() -> None:
    cfg = make_config("berlin_instances", sinr_min_db=-4.0)
    env = VectorEnv(cfg, num_envs=3)
    assert env.single_observation_space["stop_paths"].shape == (6, 3)
    assert env.single_observation_space["stop_heading_mask"].shape == (6, NUM_HEADINGS)
    obs, _ = env.reset(seed=5)
    assert env.single_observation_space.contains({k: v[0, 0] for k, v in obs.items()})
    actionable = obs["stop_heading_mask"].any(-1)  # [E, A, P]
    released = obs["passenger_mask"].astype(bool)
    assert np.all(actionable <= released)
    assert actionable.any(-1).all()  # the first request is released at step 0 and the taxi is empty


def test_uniform_arrivals_draw_counts_and_releases_in_range() -> None:
    demand = DemandConfig(arrivals="uniform", num_initial=1, min_requests=2, max_requests=5, horizon_steps=40)
    world = World(make_config("berlin_random", num_taxis=1, demand=demand))
    sites = np.array([[x, y] for x in (550.0, 1550.0, 2550.0) for y in (550.0, 1550.0, 2550.0)])
    rng = np.random.default_rng(0)
    counts = []
    for _ in range(200):
        reqs = sample_requests(world, rng, sites)
        steps = [r.release_step for r in reqs]
        counts.append(len(reqs))
        assert steps[0] == 0 and steps == sorted(steps) and max(steps) <= 40
    assert set(counts) == {2, 3, 4, 5}
    with pytest.raises(ConfigError, match="arrivals"):
        DemandConfig(arrivals="bursty")


def test_mixture_concatenates_groups_as_separate_cores() -> None:
    cfgs = [make_config("berlin_instances", sinr_min_db=t) for t in (-7.0, -3.0)]
    mix = MixtureVectorEnv(cfgs, num_envs=5)  # groups of 3 and 2 envs
    assert mix.bounds.tolist() == [0, 3, 5]
    alone = [VectorEnv(cfgs[0], num_envs=3), VectorEnv(cfgs[1], num_envs=2)]
    obs, _ = mix.reset(seed=10)
    parts = [alone[0].reset(seed=10)[0], alone[1].reset(seed=13)[0]]
    for key in obs:
        np.testing.assert_array_equal(obs[key], np.concatenate([p[key] for p in parts]))
    rng = np.random.default_rng(0)
    for _ in range(30):
        actions = rng.integers(0, NUM_HEADINGS, size=(5, 1))
        obs, rewards, terminated, truncated, _ = mix.step(actions)
        ref = [alone[0].step(actions[:3]), alone[1].step(actions[3:])]
        np.testing.assert_array_equal(rewards, np.concatenate([r[1] for r in ref]))
        np.testing.assert_array_equal(obs["self"], np.concatenate([r[0]["self"] for r in ref]))
        np.testing.assert_array_equal(terminated, np.concatenate([r[2] for r in ref]))
        np.testing.assert_array_equal(truncated, np.concatenate([r[3] for r in ref]))
    with pytest.raises(ValueError, match="observation layout"):
        MixtureVectorEnv([cfgs[0], make_config("berlin_instances", max_passengers=8)], num_envs=2)


def test_drawn_map_needs_no_extra_rows() -> None:
    """On a drawn map, features work for a fleet too (each taxi its own stops)."""
    cfg = small_config(
        radio=drawn_map(WALL), starts_m=((150.0, 150.0), (650.0, 650.0)), stop_features=True,
        requests=(Request(0, (550.0, 350.0), (650.0, 50.0)),),
    )  # fmt: skip
    obs, _ = VectorEnv(cfg, num_envs=1).reset(seed=0)
    assert obs["stop_heading_mask"].shape == (1, 2, 1, NUM_HEADINGS)
    assert obs["stop_heading_mask"][0, :, 0].sum(-1).tolist() == [1, 1]


def test_rivals_name_the_nearest_other_free_taxi_and_the_share_nearer() -> None:
    """Three taxis, one seat each; taxi 0 boards passenger B in the first step, so only taxis 1 and 2 count as
    rivals for the waiting passenger A afterwards."""
    reqs = (
        Request(0, (650.0, 650.0), (50.0, 650.0)),  # A: waits in the north-east
        Request(0, (150.0, 250.0), (650.0, 50.0)),  # B: next to taxi 0
    )
    cfg = small_config(
        "\n".join(["......."] * 7), starts_m=((150.0, 150.0), (350.0, 350.0), (550.0, 250.0)), requests=reqs,
        seats=1, stop_features=True, stop_rivals=True, patch_size=4,
    )  # fmt: skip
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=0)
    assert obs["stop_rivals"].shape == (1, 3, 2, 2)
    table, side = table_for(env.world), env.world.side_m
    a_origin = np.array([650.0, 650.0])

    def dist(pos: np.ndarray) -> float:
        return float(table.distance(pos, a_origin))

    d = [dist(env.state.pos_m[0, b]) for b in range(3)]
    assert d[2] < d[1] < d[0]  # taxi 2 nearest to A, taxi 0 farthest
    rivals = obs["stop_rivals"][0, :, 0]  # [taxi, feature] for passenger A
    np.testing.assert_allclose(rivals[:, 0], np.array([d[2], d[2], d[1]]) / side, rtol=1e-6)
    np.testing.assert_allclose(rivals[:, 1], [1.0, 0.5, 0.0])  # share of the 2 other free taxis nearer

    obs, *_ = env.step(np.array([[4, 0, 0]]))  # taxi 0 north onto B's origin; taxis 1 and 2 east
    assert env.state.pax_taxi[0, 1] == 0 and env.state.free_seats[0, 0] == 0
    d = [dist(env.state.pos_m[0, b]) for b in range(3)]
    rivals = obs["stop_rivals"][0, :, 0]
    np.testing.assert_allclose(rivals[:, 0], np.array([min(d[1], d[2]), d[2], d[1]]) / side, rtol=1e-6)
    np.testing.assert_allclose(rivals[:, 1], [1.0, float(d[2] < d[1]), float(d[1] < d[2])])  # taxi 0 is full
    assert np.all(obs["stop_rivals"][0, :, 1] == 0.0)  # B rides: no rivals for her


def _nearest_first(dist: dict[tuple[int, int], float], free: list[bool]) -> dict[int, int]:
    """Row -> taxi by the nearest-first rule written out directly: repeatedly take the globally nearest
    (taxi, row) pair whose taxi has a free seat and neither is taken yet."""
    claims: dict[int, int] = {}
    pairs = dict(dist)
    while pairs:
        (a, p), _ = min(pairs.items(), key=lambda item: (item[1], item[0]))
        if free[a]:
            claims[p] = a
            pairs = {k: v for k, v in pairs.items() if k[0] != a and k[1] != p}
        else:
            pairs = {k: v for k, v in pairs.items() if k[0] != a}
    return claims


def test_claims_are_the_nearest_first_matching_of_free_taxis_to_waiting_rows() -> None:
    """Three taxis (one seat each) and three waiting passengers: taxi 0 is next to B, taxi 2 next to C, so taxi 1
    is left with A far in the north-east; after taxi 0 boards B it is full and claims nothing, and nobody claims
    a rider."""
    reqs = (
        Request(0, (650.0, 650.0), (50.0, 650.0)),  # A
        Request(0, (150.0, 250.0), (650.0, 50.0)),  # B: 100 m north of taxi 0
        Request(0, (550.0, 350.0), (50.0, 50.0)),  # C: 100 m north of taxi 2
    )
    cfg = small_config(
        "\n".join(["......."] * 7), starts_m=((150.0, 150.0), (350.0, 450.0), (550.0, 250.0)), requests=reqs,
        seats=1, stop_features=True, stop_claims=True, patch_size=4,
    )  # fmt: skip
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=0)
    assert obs["stop_claims"].shape == (1, 3, 3, 2) and obs["stop_claims"].dtype == np.int8
    table = table_for(env.world)

    def expected_claims() -> dict[int, int]:
        s = env.state
        waiting = [p for p in range(3) if s.pax_status[0, p] == WAITING]
        dist = {(a, p): float(table.distance(s.pos_m[0, a], s.pax_origin_m[0, p])) for a in range(3) for p in waiting}
        return _nearest_first(dist, [bool(s.free_seats[0, a] > 0) for a in range(3)])

    def observed_claims(obs: dict[str, np.ndarray]) -> dict[int, int]:
        claims = obs["stop_claims"][0]  # [A, P, 2]
        out = {}
        for p in range(3):
            mine = np.flatnonzero(claims[:, p, 0])
            assert len(mine) <= 1
            if len(mine):
                out[p] = int(mine[0])
                others = np.ones(3, bool)
                others[mine[0]] = False
                assert claims[others, p, 1].all() and not claims[mine[0], p, 1]  # everyone else: another's
            else:
                assert not claims[:, p].any()
        return out

    assert observed_claims(obs) == expected_claims() == {0: 1, 1: 0, 2: 2}  # by hand, then by the rule
    obs, *_ = env.step(np.array([[4, 8, 8]]))  # taxi 0 north onto B; taxis 1 and 2 west
    assert env.state.free_seats[0, 0] == 0
    claims = observed_claims(obs)
    assert claims == expected_claims() and set(claims) == {0, 2} and 1 not in claims  # B rides: nobody claims
    assert 0 not in claims.values()  # a full taxi claims nothing


def test_the_hover_heading_flies_back_to_where_the_taxi_was_a_step_ago() -> None:
    """At the first step every endpoint is a step from the start, so the hover heading is the lowest allowed one
    (taxi 1 starts with a wall east of it: not east); after flying east it is west, after north-east south-west."""
    art = "\n".join([".......", ".......", ".......", ".......", ".......", ".......", ".#....."])
    cfg = small_config(
        art, starts_m=((350.0, 350.0), (50.0, 50.0)), requests=(Request(0, (650.0, 650.0), (650.0, 50.0)),),
        stop_features=True, stop_claims=True, patch_size=4, feasibility="endpoint_block",
    )  # fmt: skip
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=0)
    hover = obs["hover_heading_mask"][0]  # [A, 16]
    assert hover.sum(-1).tolist() == [1, 1]
    first_allowed = [int(np.flatnonzero(env.state.action_mask[0, a])[0]) for a in range(2)]
    assert first_allowed[0] == 0 and first_allowed[1] > 0  # the wall blocks taxi 1's way east
    assert hover.argmax(-1).tolist() == first_allowed
    obs, *_ = env.step(np.array([[0, 4]]))  # taxi 0 east to (450, 350); taxi 1 north to (50, 150)
    assert obs["hover_heading_mask"][0].argmax(-1).tolist() == [8, 12]  # west; south
    obs, *_ = env.step(np.array([[2, 0]]))  # taxi 0 north-east; taxi 1 east
    assert obs["hover_heading_mask"][0].argmax(-1).tolist() == [10, 8]  # south-west; west


def _brute_force_rest(table, state, a: int, first: int) -> float | None:
    """The shortest rest of the tour after stop ``first`` (2p origin, 2p + 1 destination), by trying every order
    of the other stops (pick-up before drop-off, seats respected); None beyond 8 stops (too many orders)."""
    P = state.pax_status.shape[1]
    pts = [state.pax_origin_m[0, p] if i == 0 else state.pax_dest_m[0, p] for p in range(P) for i in (0, 1)]
    todo = []
    for p in range(P):
        if state.pax_exists[0, p] and state.pax_status[0, p] == 1:
            todo += [2 * p, 2 * p + 1]
        if state.pax_exists[0, p] and state.pax_status[0, p] == 2 and state.pax_taxi[0, p] == a:
            todo.append(2 * p + 1)
    todo.remove(first)
    if len(todo) > 8:
        return None
    seats0 = int(state.free_seats[0, a]) + (-1 if first % 2 == 0 else 1)
    best = np.inf
    for order in itertools.permutations(todo):
        seats, here, total, seen = seats0, first, 0.0, {first}
        for stop in order:
            if stop % 2 == 0:
                if seats <= 0:
                    break
                seats -= 1
            else:
                if stop - 1 in [*todo, first] and stop - 1 not in seen:
                    break  # her pick-up is still ahead
                seats += 1
            total += float(table.distance(pts[here], pts[stop]))
            here = stop
            seen.add(stop)
        else:
            best = min(best, total)
    return best


def test_tour_via_stop_is_the_shortest_tour_by_brute_force() -> None:
    cfg = make_config("berlin_instances", sinr_min_db=-6.0, num_taxis=1)
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=11)
    table, side = table_for(env.world), env.world.side_m
    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(60):
        paths, heading = obs["stop_paths"][0, 0], obs["stop_heading_mask"][0, 0]
        for p in np.flatnonzero(heading.any(-1)):
            mine = env.state.pax_status[0, p] == 2
            first = 2 * p + 1 if mine else 2 * p
            goal = env.state.pax_dest_m[0, p] if mine else env.state.pax_origin_m[0, p]
            rest = _brute_force_rest(table, env.state, 0, first)
            if rest is None:
                continue
            expected = float(table.distance(env.state.pos_m[0, 0], goal)) + rest
            assert paths[p, 2] == pytest.approx(expected / side, rel=1e-5)
            assert paths[p, 2] >= paths[p, 0]
            checked += 1
        actionable = np.flatnonzero(heading.any(-1))
        action = heading[rng.choice(actionable)].argmax() if len(actionable) else 0
        obs, _, terminated, _, _ = env.step(np.array([[action]]))
        if terminated[0]:
            break
    assert checked > 20


def _python_nearest_rest(table, state, a: int, first: int) -> float:
    """The rest of the tour after stop ``first`` in nearest-stop order (pick-ups while a seat is free)."""
    P = state.pax_status.shape[1]
    pts = [state.pax_origin_m[0, p] if i == 0 else state.pax_dest_m[0, p] for p in range(P) for i in (0, 1)]
    todo = {2 * p for p in range(P) if state.pax_exists[0, p] and state.pax_status[0, p] == 1}
    todo |= {2 * p + 1 for p in range(P) if state.pax_status[0, p] == 2 and state.pax_taxi[0, p] == a}
    seats = int(state.free_seats[0, a])
    here, total = first, 0.0
    todo.discard(first)
    if first % 2 == 0:
        todo.add(first + 1)
    seats += -1 if first % 2 == 0 else 1
    while True:
        options = [i for i in sorted(todo) if i % 2 == 1 or seats > 0]
        if not options:
            return total
        dists = [float(table.distance(pts[here], pts[i])) for i in options]
        k = int(np.argmin(dists))
        total, here = total + dists[k], options[k]
        todo.discard(here)
        if here % 2 == 0:
            todo.add(here + 1)
        seats += -1 if here % 2 == 0 else 1


def test_beyond_twelve_pending_stops_tours_follow_the_nearest_stop_order() -> None:
    demand = DemandConfig(num_initial=8, rate_per_step=0.0, max_requests=8)
    cfg = make_config("berlin_random", num_taxis=1, demand=demand, stop_features=True, sinr_min_db=-5.0)
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=4)
    table, side = table_for(env.world), env.world.side_m
    heading = obs["stop_heading_mask"][0, 0]
    rows = np.flatnonzero(heading.any(-1))
    assert len(rows) == 8  # 8 waiting passengers: 16 pending stops
    for p in rows:
        expected = float(table.distance(env.state.pos_m[0, 0], env.state.pax_origin_m[0, p]))
        expected += _python_nearest_rest(table, env.state, 0, 2 * p)
        assert obs["stop_paths"][0, 0, p, 2] == pytest.approx(expected / side, rel=1e-5)


def _costing_every_move(world: World, table, allowed: np.ndarray, x: float, y: float, gx: float, gy: float) -> int:  # type: ignore[no-untyped-def]
    """The progress heading as first written: every allowed move costed in order, the first least one kept (the
    same float operations as the kernel, in Python)."""
    w = world.arrays
    best, best_cost = -1, np.inf
    for h in range(NUM_HEADINGS):
        if not allowed[h]:
            continue
        qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
        if (qx - gx) ** 2 + (qy - gy) ** 2 <= w.radius_m * w.radius_m:
            cost = w.step_m
        else:
            cost = w.step_m + table_distance(table.arrays, qx, qy, gx, gy)
        if cost < best_cost:
            best, best_cost = h, cost
    return best


def test_progress_heading_equals_costing_every_move_in_order() -> None:
    env = VectorEnv(make_config("berlin_random", num_taxis=1, stop_features=True, sinr_min_db=-5.0), num_envs=1)
    world, table = env.world, table_for(env.world).fill()
    rng = np.random.default_rng(5)
    side, radius = world.side_m, world.cfg.radius_m
    cases = [(rng.uniform(0, side, 2), rng.uniform(0, side, 2)) for _ in range(400)]
    # the stop straight north, east or diagonal (mirror-image moves may tie), and within one move (several moves
    # end within the pick-up radius: all cost the move alone, the lowest heading wins)
    centre = np.array([side / 2, side / 2])
    cases += [(centre, centre + d) for d in ([0.0, 700.0], [700.0, 0.0], [500.0, 500.0], [0.0, 30.0], [10.0, 0.0])]
    mask = np.empty((1, NUM_HEADINGS), bool)
    ties = 0
    for pos, goal in cases:
        action_mask(pos[None], world.arrays, mask)
        for allowed in (mask[0], mask[0] & (rng.random(NUM_HEADINGS) < 0.5)):
            expected = _costing_every_move(world, table, allowed, pos[0], pos[1], goal[0], goal[1])
            got = _progress_heading(allowed, world.arrays, table.arrays, *pos, *goal)
            assert got == expected, (pos, goal, allowed)
        ends = pos + world.moves_m[mask[0]]
        ties += int((np.linalg.norm(ends - goal, axis=-1) <= radius).sum() > 1)
    assert ties >= 1  # a case with several moves ending at the stop was checked


@pytest.mark.parametrize("num_taxis", [4, 8])
def test_kept_tour_rests_equal_rests_computed_afresh_every_step(num_taxis: int) -> None:
    """The tour rests are kept in the state while a taxi's stops and seats stay the same (4 taxis: 24 passenger
    rows, a key with a bit per stop, more than 12 stops pending: nearest-stop tours; 8 taxis: 48 rows, the
    progress key). Every step's stop features equal those computed from a copy whose kept rests are cleared."""
    env = VectorEnv(make_config("berlin_fleet", num_taxis=num_taxis, separation="none"), num_envs=2)
    table = table_for(env.world).fill()
    obs, _ = env.reset(seed=6)
    rng = np.random.default_rng(6)
    kept_steps = 0
    for _ in range(60):
        keys = env.state.stop_tour_key.copy()
        actions = np.argmax(rng.random(obs["action_mask"].shape) * obs["action_mask"], axis=-1)
        obs, *_ = env.step(actions)
        kept_steps += int(((env.state.stop_tour_key == keys) & (keys != -1)).sum())
        fresh = env.state.copy()
        fresh.stop_tour_key[:] = -1
        fresh.stop_tour_m[:] = np.nan
        paths, heading = np.empty_like(obs["stop_paths"]), np.empty_like(obs["stop_heading_mask"])
        assert stop_features(fresh, env.world.arrays, table.arrays, paths, heading)
        np.testing.assert_array_equal(obs["stop_paths"], paths)
        np.testing.assert_array_equal(obs["stop_heading_mask"], heading)
    many = [tours._pending_stops(env.state, e, a, np.empty(12, np.int64), np.empty(12, np.int64)) < 0
            for e in range(2) for a in range(num_taxis)]  # fmt: skip
    assert kept_steps > 50 and any(many)  # rests were kept, some of them nearest-stop tours


def test_stop_distances_fill_the_memo_with_the_plain_lookups_and_stop_at_a_missing_row() -> None:
    """_stop_distances (prepared corners for the pairs not in the memo) gives table_distance's numbers bit for bit,
    keeps them, reads a kept pair from the memo as it is, and answers False at the first row not computed yet."""
    env = VectorEnv(make_config("berlin_random", stop_features=True), num_envs=1)
    table = table_for(env.world)
    rng = np.random.default_rng(7)
    pts = rng.uniform(0.0, env.world.side_m, (10, 2))
    table.ensure(pts)
    stops = np.array([0, 3, 4, 7, 9], np.int64)
    memo = np.full((10, 10), np.nan)
    memo[3, 4] = 123.0  # a kept pair is read, not looked up again
    dist = np.empty((5, 5))
    assert tours._stop_distances(memo, pts, stops, 5, table.arrays, dist)
    want = np.array([[0.0 if i == j else table_distance(table.arrays, *pts[i], *pts[j]) for j in stops] for i in stops])
    want[1, 2] = 123.0
    np.testing.assert_array_equal(dist, want)
    np.testing.assert_array_equal(memo[np.ix_(stops, stops)][~np.eye(5, dtype=bool)], want[~np.eye(5, dtype=bool)])
    none_yet = table.arrays._replace(distance_m=np.full_like(table.arrays.distance_m, np.nan))  # no row computed
    assert not tours._stop_distances(np.full((10, 10), np.nan), pts, stops, 5, none_yet, dist)
