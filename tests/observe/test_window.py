"""The passenger window (``EnvConfig.passenger_window``, :mod:`uamfleet.observe.window`): each taxi observes its riders,
then its nearest waiting requests, K rows; the rows are the full observation's rows of those passengers. The rule is
checked here against a direct computation written from docs/rules.md, on a drawn map whose wall makes the
feasible-path order differ from the straight-line one."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
import torch
from conftest import small_config

import uamfleet
from uamfleet.policies import make
from uamfleet.config import ConfigError, EnvConfig, Request
from uamfleet.observe import spec as layout_module
from uamfleet.observe.spec import PASSENGER_AXIS_FIELDS, computed_layout, observation_layout
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.types import DELIVERED, ON_BOARD, STOP_CLAIM_FEATURES, WAITING

# A wall with one gap at the north edge: a request just across it is near in a straight line, far along paths.
WALL_7 = """
.......
...#...
...#...
...#...
...#...
...#...
.......
"""
REQUESTS = (
    Request(0, (450.0, 250.0), (650.0, 650.0)),  # across the wall from the taxis in the west
    Request(0, (150.0, 550.0), (50.0, 50.0)),
    Request(0, (50.0, 350.0), (650.0, 50.0)),
    Request(2, (250.0, 650.0), (550.0, 550.0)),
    Request(4, (650.0, 150.0), (150.0, 150.0)),
    Request(6, (150.0, 150.0), (550.0, 350.0)),
    Request(9, (550.0, 650.0), (50.0, 650.0)),
    Request(12, (250.0, 50.0), (650.0, 350.0)),
)
STARTS = ((250.0, 250.0), (150.0, 450.0), (550.0, 450.0))


def wall_config(window: int | None, stops: bool = True, claims: bool = False, **overrides: object):
    return small_config(
        WALL_7, starts_m=STARTS, requests=REQUESTS, seats=2, time_limit_steps=60, passenger_window=window,
        stop_features=stops, stop_claims=claims, **overrides,
    )  # fmt: skip


def expected_rows(env: VectorEnv, e: int, a: int, K: int, by_path: bool) -> list[int]:
    """Taxi a's window written out from docs/rules.md: riders in request order, then waiting requests by distance
    to their origin (feasible path from the env's table, or straight line), ties by request index; -1 pads."""
    s = env.state
    riders = [p for p in range(s.pax_status.shape[1]) if s.pax_status[e, p] == ON_BOARD and s.pax_taxi[e, p] == a]
    waiting = [p for p in range(s.pax_status.shape[1]) if s.pax_exists[e, p] and s.pax_status[e, p] == WAITING]
    pos = s.pos_m[e, a]
    if by_path:
        dist = {p: float(env.observer.table.distance(pos, s.pax_origin_m[e, p])) for p in waiting}
    else:
        dist = {p: float(np.hypot(*(s.pax_origin_m[e, p] - pos))) for p in waiting}
    rows = riders + sorted(waiting, key=lambda p: (dist[p], p))
    return (rows + [-1] * K)[:K]


@pytest.mark.parametrize("by_path", [True, False])
def test_each_taxi_sees_its_riders_then_its_nearest_waiting_requests(by_path: bool) -> None:
    K = 3
    full_env = VectorEnv(wall_config(None, stops=by_path, claims=by_path), num_envs=2, autoreset=False)
    env = VectorEnv(wall_config(K, stops=by_path, claims=by_path), num_envs=2, autoreset=False)
    full, _ = full_env.reset(seed=5)
    obs, _ = env.reset(seed=5)
    rng = np.random.default_rng(0)
    fields = [name for name in PASSENGER_AXIS_FIELDS if name in obs]
    path_differs = riders_seen = 0
    for _ in range(40):
        for e in range(2):
            for a in range(len(STARTS)):
                rows = expected_rows(env, e, a, K, by_path)
                if by_path:
                    path_differs += rows != expected_rows(env, e, a, K, by_path=False)
                riders_seen += sum(env.state.pax_status[e, p] == ON_BOARD for p in rows if p >= 0)
                for name in fields:
                    for j, p in enumerate(rows):
                        want = full[name][e, a, p] if p >= 0 else np.zeros_like(full[name][e, a, 0])
                        np.testing.assert_array_equal(obs[name][e, a, j], want, err_msg=f"{name} slot {j} taxi {a}")
        actions = np.where(obs["action_mask"] > 0, rng.random(obs["action_mask"].shape), -1).argmax(-1)
        obs, *_ = env.step(actions)
        full, *_ = full_env.step(actions)
        np.testing.assert_array_equal(env.state.pos_m, full_env.state.pos_m)  # the window changes no dynamics
    assert riders_seen > 0, "the scene never had a rider in a window"
    if by_path:
        assert path_differs > 0, "the scene never told the feasible-path order from the straight-line one"


def test_a_taxis_claim_is_in_its_window_when_the_window_holds_seats_plus_taxis_minus_one() -> None:
    K = 2 + len(STARTS) - 1  # seats + A - 1 (docs/rules.md "Passenger window")
    full_env = VectorEnv(wall_config(None, claims=True), num_envs=2, autoreset=False)
    window_env = VectorEnv(wall_config(K, claims=True), num_envs=2, autoreset=False)
    full, _ = full_env.reset(seed=1)
    window_env.reset(seed=1)
    rng = np.random.default_rng(2)
    me = STOP_CLAIM_FEATURES.index("claimed_by_me")
    claims = 0
    for _ in range(40):
        rows = window_env.observer.window_rows(window_env.state)
        for e, a, p in zip(*np.nonzero(full["stop_claims"][..., me]), strict=True):
            claims += 1
            assert p in rows[e, a], f"taxi {a}'s claim {p} is outside its window {rows[e, a]}"
        actions = np.where(full["action_mask"] > 0, rng.random(full["action_mask"].shape), -1).argmax(-1)
        full, *_ = full_env.step(actions)
        window_env.step(actions)
    assert claims > 0


def test_the_window_sets_the_passenger_axis_of_exactly_the_passenger_fields() -> None:
    every = dict(stops=True, rivals=True, claims=True, lookahead=True)
    three, four = layout_module._layout(3, 2, 3, 2, **every), layout_module._layout(4, 2, 3, 2, **every)
    follows_p = [name for name in three if three[name].shape != four[name].shape]
    assert follows_p == list(PASSENGER_AXIS_FIELDS)
    assert all(three[n].shape[1:] == four[n].shape[1:] and three[n].shape[0] == 3 for n in follows_p)
    cfg = wall_config(3, claims=True, heading_lookahead=True)
    windowed, computed = observation_layout(cfg), computed_layout(cfg)
    assert [windowed[n].shape[0] for n in PASSENGER_AXIS_FIELDS] == [3] * len(PASSENGER_AXIS_FIELDS)
    assert [computed[n].shape[0] for n in PASSENGER_AXIS_FIELDS] == [len(REQUESTS)] * len(PASSENGER_AXIS_FIELDS)
    assert observation_layout(wall_config(None)) == computed_layout(wall_config(None))  # no window: as before


def test_a_window_must_hold_the_taxis_riders() -> None:
    with pytest.raises(ConfigError, match=r"passenger_window=1 must be an integer in \[2, "):
        wall_config(1)
    with pytest.raises(ConfigError, match=r"passenger_window=2\.5"):
        wall_config(2.5)
    assert wall_config(20).observed_passengers == 20  # more rows than requests: padding


# ---- one policy, any number of requests ------------------------------------------------------------------------


def fly_steps(policy: GreedyPolicy, cfg: EnvConfig, steps: int) -> tuple[dict[str, tuple[int, ...]], int]:
    """``policy`` flown on the world ``cfg`` observed by its spec, ``steps`` steps or to the episode's end: its
    observation shapes (the same at every step) and the passengers delivered."""
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=policy.spec)
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    shapes = {k: v.shape for k, v in obs.items()}
    for _ in range(steps):
        obs, _, done, trunc, _ = env.step(policy(obs))
        assert {k: v.shape for k, v in obs.items()} == shapes
        if done.all() or trunc.all():
            break
    return shapes, int((env.state.pax_status == DELIVERED).sum())


def open_map_requests(count: int, window_steps: int, seed: int) -> tuple[Request, ...]:
    """``count`` requests between random block centres of a 12 x 12 open map, released over ``window_steps``."""
    rng = np.random.default_rng(seed)
    centres = rng.integers(0, 12, size=(count, 2, 2)) * 100.0 + 50.0
    centres[:, 1, 0] = np.where((centres[:, 0] == centres[:, 1]).all(-1), (centres[:, 1, 0] + 300.0) % 1200.0,
                                centres[:, 1, 0])  # fmt: skip
    release = np.sort(rng.integers(0, window_steps, count))
    return tuple(Request(int(r), tuple(c[0]), tuple(c[1])) for r, c in zip(release, centres, strict=True))


@pytest.fixture
def one_torch_thread() -> Iterator[None]:
    """Small forwards, one per step: on a shared 2-core machine two intra-op threads made them 20 x slower
    (measured: 18 s against 0.9 s for 20 steps of 8 taxis under a load average of 11)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.mark.usefixtures("one_torch_thread")
def test_one_policy_reads_24_and_200_requests_with_the_same_shapes() -> None:
    """The shipped fleet policy, which reads its 24 trained rows as a window (no argument needed), on 8 taxis and 24
    or 200 requests released over 30 minutes (600 steps of 3 s) on a drawn open map: the first 40 steps (the whole
    episodes on Berlin: below)."""
    policy = uamfleet.pretrained("berlin_fleet")
    assert policy.spec is not None and policy.spec.passenger_window == 24
    starts = tuple((100.0 * i + 50.0, 100.0 * (i % 3) + 50.0) for i in range(8))
    shapes = []
    for count in (24, 200):
        cfg = small_config("\n".join(["." * 12] * 12), starts_m=starts, requests=open_map_requests(count, 600, 1),
                           time_limit_steps=1200, sinr_min_db=-5.0, hover_action=True)  # fmt: skip
        shapes.append(fly_steps(policy, cfg, steps=40)[0])
    assert shapes[0] == shapes[1] and shapes[0]["passengers"] == (1, 8, 24, 12)


@pytest.mark.usefixtures("one_torch_thread")
@pytest.mark.parametrize("requests", [pytest.param(24, marks=pytest.mark.slow), 200])  # 200: 3.5 s on an idle core
def test_one_policy_flies_8_taxis_over_a_30_minute_window_at_24_and_200_requests(requests: int) -> None:
    """Issue 21's "any load": the shipped fleet policy, as a user flies it (the hover action of the fleet presets,
    the shield), delivers everyone of a 30-minute shift on Berlin; berlin_fleet_v1 as it was measured."""
    policy = uamfleet.pretrained("berlin_fleet")
    cfg = make_fleet_instance("berlin", 3, 8, requests, arrival_window_s=1800.0, separation="shield", hover_action=True)
    assert cfg.num_passengers == requests and cfg.time_limit_steps > 600  # the instance's own rows and time limit
    _, delivered = fly_steps(policy, cfg, steps=cfg.time_limit_steps)
    assert delivered == requests
    first = make("learned", source="berlin_fleet_v1", passenger_window=24)
    cfg = make_fleet_instance("berlin", 3, 8, requests, arrival_window_s=1800.0, hover_action=False)
    _, delivered = fly_steps(first, cfg, steps=cfg.time_limit_steps)
    assert delivered == requests  # as measured (docs/results.md, issue 21 part 2)
