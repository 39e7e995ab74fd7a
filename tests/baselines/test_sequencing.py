"""Pick-up and delivery sequencing: the DP against brute force, hand-solved line instances, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pdp_oracle import brute_force_pdp, count_feasible_sequences, every_plan

from uamfleet.baselines.sequencing import (
    _GAP,
    OBJECTIVES,
    Plan,
    _dp_labels,
    _problem,
    solve_in_order,
    solve_pdp,
    solve_pdp_each,
)


def _line(xs: list[float]) -> np.ndarray:
    """Distances between points on the x-axis: [start, P0 origin, P0 destination, P1 origin, ...]."""
    x = np.asarray(xs, dtype=float)
    return np.abs(x[:, None] - x[None, :])


def _random_instance(rng: np.random.Generator, n: int, ties: bool) -> dict:
    if ties:  # a 3 x 3 integer lattice with Manhattan distances: many equal totals
        pts = rng.integers(0, 2, size=(1 + 2 * n, 2)).astype(float)
        dist = np.abs(pts[:, None] - pts[None]).sum(-1)
        release = rng.integers(0, 4, size=n).astype(float) * rng.integers(0, 2, size=n)
    else:
        pts = rng.uniform(0, 3000, size=(1 + 2 * n, 2))
        dist = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))
        dist[0] *= rng.uniform(1.0, 1.3)  # asymmetric on purpose: any metric is allowed
        release = rng.uniform(0, 120, size=n) * rng.integers(0, 2, size=n)
    capacity = int(rng.choice([1, 2], p=[0.3, 0.7]))
    state = rng.choice(3, size=n, p=[0.8, 0.1, 0.1]) if rng.random() < 0.5 else np.zeros(n, int)  # waiting/on/done
    while (state == 1).sum() > capacity:
        state[np.flatnonzero(state == 1)[0]] = 0
    return dict(
        dist_m=dist,
        speed_mps=1.0 if ties else 33.3,
        release_s=release.tolist(),
        capacity=capacity,
        on_board=(state == 1).tolist(),
        done=(state == 2).tolist(),
        start_s=float(rng.uniform(0, 5)) if not ties else 0.0,
    )


def _check_feasible(plan: Plan, kwargs: dict) -> None:
    """Precedence, capacity, every non-done passenger delivered once, pick-ups not before release."""
    n = len(kwargs["release_s"])
    riding = {i for i in range(n) if kwargs["on_board"][i]}
    delivered: list[int] = []
    for (i, kind), t in zip(plan.stops, plan.arrival_s, strict=True):
        if kind == "pickup":
            assert i not in riding and i not in delivered
            assert t >= kwargs["release_s"][i]
            riding.add(i)
            assert len(riding) <= kwargs["capacity"]
        else:
            riding.remove(i)  # KeyError = a drop-off before its pick-up
            delivered.append(i)
    assert sorted(delivered) == [i for i in range(n) if not kwargs["done"][i]]
    assert list(plan.arrival_s) == sorted(plan.arrival_s)


@pytest.mark.parametrize("objective", ["makespan", "distance", "ride"])
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5])
def test_dp_matches_brute_force(n: int, objective: str) -> None:
    rng = np.random.default_rng(100 * n + len(objective))
    for trial in range(16 if n < 5 else 6):
        kwargs = _random_instance(rng, n, ties=trial % 2 == 1)
        dp = solve_pdp(**kwargs, objective=objective)
        bf = brute_force_pdp(**kwargs, objective=objective)
        assert dp == bf, kwargs
        _check_feasible(dp, kwargs)
        again = solve_in_order(
            kwargs["dist_m"],
            kwargs["speed_mps"],
            kwargs["release_s"],
            dp.stops,
            start_s=kwargs["start_s"],
            on_board=kwargs["on_board"],
            done=kwargs["done"],
            capacity=kwargs["capacity"],
        )
        assert again == dp


@pytest.mark.parametrize("objective", ["makespan", "distance", "ride"])
def test_dp_labels_the_same_when_buckets_widen(objective: str) -> None:
    """The compiled DP keeps a state's labels in a row that widens when a bucket outgrows it: with one label of
    room (the widening taken at every second label) it leaves the same final labels, in the same order, as with
    room for all, and the plan is the brute force's."""
    rng = np.random.default_rng(7 + len(objective))
    widened = 0
    for trial in range(24):
        kwargs = _random_instance(rng, int(rng.integers(2, 6)), ties=trial % 2 == 1)
        pb = _problem(**{k: kwargs[k] for k in ("dist_m", "speed_mps", "release_s", "capacity", "on_board", "done",
                                                "start_s")}, objective=objective)  # fmt: skip
        args = (
            pb.travel_array, pb.dist_array, np.array(pb.release_s), np.array(pb.active, dtype=np.int64),
            np.array([i in pb.on_board for i in pb.active]), pb.capacity, pb.start_s, OBJECTIVES.index(objective),
            0.0, _GAP,
        )  # fmt: skip
        roomy, tight = _dp_labels(*args, 64), _dp_labels(*args, 1)
        for a, b in zip(roomy, tight, strict=True):
            np.testing.assert_array_equal(a, b)
        widened += len(roomy[0]) > 1
        assert solve_pdp(**kwargs, objective=objective) == brute_force_pdp(**kwargs, objective=objective)
    assert widened > 0  # some final layer held more than one label: the widening was taken


@pytest.mark.parametrize("objective", ["makespan", "distance", "ride"])
def test_solve_pdp_each_is_solve_pdp_of_each_subset_alone(objective: str) -> None:
    """Every subset solved over the whole matrix gives, to the bit, the plan of its own sub-matrix (ties made on
    purpose on half the draws; riders in every subset)."""
    rng = np.random.default_rng(31 + len(objective))
    for trial in range(20):
        n = int(rng.integers(1, 7))
        kwargs = _random_instance(rng, n, ties=trial % 2 == 1)
        kwargs.pop("done")
        riding = [i for i in range(n) if kwargs["on_board"][i]]
        others = [i for i in range(n) if i not in riding]
        subsets = [sorted(riding + [int(i) for i in rng.choice(others, size=m, replace=False)])
                   for m in rng.integers(0, min(len(others), 4) + 1, size=5)]  # fmt: skip
        beta = 1.0 if objective == "ride" and trial % 4 == 0 else 0.0
        plans = solve_pdp_each(**kwargs, subsets=subsets, objective=objective, wait_weight=beta)
        for subset, plan in zip(subsets, plans, strict=True):
            nodes = [0] + [1 + 2 * i + d for i in subset for d in (0, 1)]
            alone = solve_pdp(
                kwargs["dist_m"][np.ix_(nodes, nodes)],
                kwargs["speed_mps"],
                [kwargs["release_s"][i] for i in subset],
                capacity=kwargs["capacity"],
                on_board=[kwargs["on_board"][i] for i in subset],
                start_s=kwargs["start_s"],
                objective=objective,
                wait_weight=beta,
            )
            assert plan == alone, (subset, kwargs)


def test_solve_pdp_each_refuses_unordered_subsets_and_riders_left_out() -> None:
    dist = _line([0, 1, 2, 3, 4])
    with pytest.raises(ValueError, match="ascending"):
        solve_pdp_each(dist, 1.0, [0.0, 0.0], [[1, 0]])
    with pytest.raises(ValueError, match="on board"):
        solve_pdp_each(dist, 1.0, [0.0, 0.0], [[1]], on_board=[True, False])


@pytest.mark.parametrize("wait_weight", [0.5, 1.0, 4.0])
@pytest.mark.parametrize("n", [2, 3, 4])
def test_wait_weight_minimises_ride_plus_weighted_wait(n: int, wait_weight: float) -> None:
    """The DP against the brute force with the same weight, and its cost against the least ride + β · wait over
    every feasible plan's plain totals (an independent sum: the oracle's plans never see the weight)."""
    rng = np.random.default_rng(1000 * n + int(10 * wait_weight))
    moved = 0
    for trial in range(12):
        kwargs = _random_instance(rng, n, ties=trial % 2 == 1)
        dp = solve_pdp(**kwargs, objective="ride", wait_weight=wait_weight)
        assert dp == brute_force_pdp(**kwargs, objective="ride", wait_weight=wait_weight), kwargs
        _check_feasible(dp, kwargs)
        least = min(p.total_ride_s + wait_weight * p.total_wait_s for p in every_plan(**kwargs))
        assert dp.total_ride_s + wait_weight * dp.total_wait_s == pytest.approx(least, abs=1e-6)
        plain = solve_pdp(**kwargs, objective="ride")
        assert dp.total_wait_s <= plain.total_wait_s + 1e-6  # weighing waits never lengthens them
        moved += dp.nodes != plain.nodes
    assert moved > 0 or n == 2  # the weight changed some plans (n = 2: see the hand-solved line below)


def test_wait_weight_trades_ride_for_wait() -> None:
    dist = _line([0, 4, 2, 5, 10])  # start 0; P0 4 -> 2; P1 5 -> 10; both requested at 0
    # P0 first: 0 -> 4 (t 4) -> 2 (t 6) -> 5 (t 9) -> 10 (t 14): rides 6 + 14 = 20, waits 4 + 9 = 13.
    # Pool, P0 dropped first: 0 -> 4 (4) -> 5 (5) -> 2 (8) -> 10 (16): rides 8 + 16 = 24, waits 4 + 5 = 9.
    # P1 first: 0 -> 5 (5) -> 10 (10) -> 4 (16) -> 2 (18): rides 18 + 10 = 28, waits 16 + 5 = 21.
    plain = solve_pdp(dist, 1.0, [0.0, 0.0], objective="ride")
    assert plain.nodes == (1, 2, 3, 4) and (plain.total_ride_s, plain.total_wait_s) == (20.0, 13.0)
    # With β = 2 the costs are 20 + 26 = 46 against 24 + 18 = 42 for the pool: the pool wins.
    weighted = solve_pdp(dist, 1.0, [0.0, 0.0], objective="ride", wait_weight=2.0)
    assert weighted.nodes == (1, 3, 2, 4) and (weighted.total_ride_s, weighted.total_wait_s) == (24.0, 9.0)
    # At β = 0.5: 20 + 6.5 = 26.5 against 24 + 4.5 = 28.5: still P0 first.
    assert solve_pdp(dist, 1.0, [0.0, 0.0], objective="ride", wait_weight=0.5).nodes == (1, 2, 3, 4)


@pytest.mark.parametrize(("objective", "wait_weight"), [("ride", -1.0), ("ride", float("nan")), ("distance", 1.0)])
def test_bad_wait_weight_is_refused(objective: str, wait_weight: float) -> None:
    with pytest.raises(ValueError, match="wait_weight"):
        solve_pdp(_line([0, 1, 2]), 1.0, [0.0], objective=objective, wait_weight=wait_weight)


def test_capacity_one_never_carries_two() -> None:
    rng = np.random.default_rng(7)
    for _ in range(10):
        kwargs = _random_instance(rng, 5, ties=False)
        kwargs["capacity"] = 1
        kwargs["on_board"] = [False] * 5
        plan = solve_pdp(**kwargs)
        # With one seat every pick-up is followed directly by its own drop-off.
        for (i, kind), (j, next_kind) in zip(plan.stops[::2], plan.stops[1::2], strict=True):
            assert (kind, next_kind, i) == ("pickup", "dropoff", j)


@pytest.mark.parametrize(("n", "capacity", "expected"), [(4, 2, 648), (5, 2, 9720), (3, 3, 90), (0, 2, 1)])
def test_count_feasible_sequences(n: int, capacity: int, expected: int) -> None:
    assert count_feasible_sequences(n, capacity) == expected  # (3, 3): unconstrained 6!/2^3


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5])
def test_count_matches_closed_forms(n: int) -> None:
    assert count_feasible_sequences(n, 2) == math.factorial(n) * 3 ** (n - 1)  # 648 for N = 4, 9,720 for N = 5
    assert count_feasible_sequences(n, 1) == math.factorial(n)


# -- hand-solved instances on a line (speed 1 m/s, so times equal distances) --------------------------------------
def test_line_pooling_and_one_seat() -> None:
    dist = _line([0, 1, 3, 2, 4])  # start 0; P0 1 -> 3; P1 2 -> 4
    # Two seats: sweep right once, picking P1 up before dropping P0.
    plan = solve_pdp(dist, 1.0, [0.0, 0.0])
    assert plan.stops == ((0, "pickup"), (1, "pickup"), (0, "dropoff"), (1, "dropoff"))
    assert plan.nodes == (1, 3, 2, 4)
    assert plan.arrival_s == (1.0, 2.0, 3.0, 4.0)
    assert (plan.finish_s, plan.distance_m, plan.total_ride_s, plan.total_wait_s) == (4.0, 4.0, 7.0, 3.0)
    # One seat: P0 first (0->1->3, back to 2, on to 4: 1 + 2 + 1 + 2 = 6) beats P1 first (2 + 2 + 3 + 2 = 9).
    plan = solve_pdp(dist, 1.0, [0.0, 0.0], capacity=1)
    assert plan.nodes == (1, 2, 3, 4)
    assert plan.finish_s == 6.0


def test_waiting_at_an_origin_beats_delivering_first() -> None:
    dist = _line([0, 2, 4, 1, 5])  # start 0; P0 2 -> 4 requested at t = 3; P1 1 -> 5 at t = 0
    plan = solve_pdp(dist, 1.0, [3.0, 0.0])
    # Pick P1 up at t = 1, wait at x = 2 until P0's request at t = 3, then 4 and 5: nothing can end before 6.
    assert plan.nodes == (3, 1, 2, 4)
    assert plan.arrival_s == (1.0, 3.0, 5.0, 6.0)
    assert plan.total_wait_s == 1.0  # P1 waited 1 s, P0 0 s
    assert plan.total_ride_s == 2.0 + 6.0
    # Delivering P1 first never waits but ends at 10.
    direct = solve_in_order(dist, 1.0, [3.0, 0.0], [(1, "pickup"), (1, "dropoff"), (0, "pickup"), (0, "dropoff")])
    assert direct.arrival_s == (1.0, 5.0, 8.0, 10.0)


def test_ties_broken_by_ride_time_then_sequence() -> None:
    dist = _line([0, 2, 3, 0, 3])  # P0 2 -> 3 requested at t = 10; P1 0 -> 3 (at the start) at t = 0
    # Every order ends at 11. Delivering P1 before fetching P0 gives rides 3 + 1 = 4; pooling gives 11 + 1 = 12.
    plan = solve_pdp(dist, 1.0, [10.0, 0.0])
    assert plan.finish_s == 11.0
    assert plan.nodes == (3, 4, 1, 2)
    assert plan.total_ride_s == 4.0
    # By distance pooling wins (3 m against 5 m); its two drop-off orders tie on everything but the sequence.
    plan = solve_pdp(dist, 1.0, [10.0, 0.0], objective="distance")
    assert (plan.distance_m, plan.finish_s, plan.total_ride_s) == (3.0, 11.0, 12.0)
    assert plan.nodes == (3, 1, 2, 4)
    assert brute_force_pdp(dist, 1.0, [10.0, 0.0], objective="distance") == plan


def test_on_board_and_done_passengers() -> None:
    dist = _line([0, -5, 10, 3, 4])  # P0 on board (requested at 50) -> 10; P1 done
    plan = solve_pdp(dist, 1.0, [50.0, 0.0], on_board=[True, False], done=[False, True], start_s=100.0)
    assert plan.stops == ((0, "dropoff"),)
    assert plan.arrival_s == (110.0,)
    assert (plan.total_ride_s, plan.total_wait_s, plan.distance_m) == (60.0, 0.0, 10.0)


def test_nothing_to_do() -> None:
    empty = solve_pdp(np.zeros((1, 1)), 10.0, [], start_s=7.0)
    assert empty == Plan(stops=(), nodes=(), arrival_s=(), finish_s=7.0, distance_m=0.0, total_ride_s=0.0,
                         total_wait_s=0.0)  # fmt: skip
    all_done = solve_pdp(_line([0, 1, 2]), 1.0, [0.0], done=[True], start_s=3.0)
    assert all_done.stops == () and all_done.finish_s == 3.0


def test_solve_in_order_appends_late_request() -> None:
    dist = _line([0, 1, 3, 2, 4])
    order = [(0, "pickup"), (0, "dropoff"), (1, "pickup"), (1, "dropoff")]
    plan = solve_in_order(dist, 1.0, [0.0, 20.0], order)
    assert plan.arrival_s == (1.0, 3.0, 20.0, 22.0)
    assert plan.distance_m == 1 + 2 + 1 + 2


# -- bad input ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("dist", "release", "kwargs", "match"),
    [
        (np.zeros((3, 2)), [0.0], {}, "square"),
        (np.zeros((4, 4)), [0.0], {}, "1 \\+ 2N = 3"),
        (-_line([0, 1, 2]), [0.0], {}, r"dist_m\[0, 1\] = -1.0 is negative"),
        (np.full((3, 3), np.inf), [0.0], {}, "non-finite"),
        (_line([0, 1, 2]), [0.0], {"capacity": 0}, "capacity must be an integer >= 1"),
        (_line([0, 1, 2]), [0.0], {"objective": "fastest"}, "unknown objective 'fastest'"),
        (_line([0, 1, 2]), [0.0], {"on_board": [True, False]}, "on_board has 2 entries"),
        (_line([0, 1, 2]), [0.0], {"on_board": [True], "done": [True]}, "both on_board and done"),
        (_line([0, 1, 2, 3, 4]), [0.0, 0.0], {"on_board": [True, True], "capacity": 1}, "raise capacity"),
        (_line([0, 1, 2]), [math.nan], {}, "release_s must be finite"),
        (_line([0, 1, 2]), [0.0], {"start_s": math.inf}, r"start_s must be a finite time in seconds, got inf"),
        (np.zeros((19, 19)), [0.0] * 9, {}, "N = 9 .* insertion heuristic"),
    ],
)
def test_bad_input(dist: np.ndarray, release: list[float], kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        solve_pdp(dist, 1.0, release, **kwargs)


def test_bad_speed() -> None:
    with pytest.raises(ValueError, match="speed_mps must be a finite number > 0"):
        solve_pdp(_line([0, 1, 2]), 0.0, [0.0])


@pytest.mark.parametrize(
    ("order", "kwargs", "match"),
    [
        ([(0, "dropoff"), (0, "pickup")], {}, r"order\[0\] = \(0, 'dropoff'\): drop-off before pick-up"),
        ([(0, "pickup"), (1, "pickup"), (0, "dropoff"), (1, "dropoff")], {"capacity": 1}, r"order\[1\].*full"),
        ([(0, "pickup"), (0, "dropoff")], {}, r"never delivers passenger 1; add \(1, 'pickup'\)"),
        ([(0, "pickup"), (0, "pickup")], {}, r"order\[1\].*already served"),
        ([(0, "board")], {}, "kind must be 'pickup' or 'dropoff'"),
        ([(5, "pickup")], {}, r"passenger must lie in \[0, 1\]"),
        ([(0, "pickup"), (0, "dropoff"), (1, "pickup"), (1, "dropoff")], {"done": [True, False]}, "already done"),
        ([(0, "pickup")], {"on_board": [True, False]}, "already served"),
    ],
)
def test_solve_in_order_rejects_bad_orders(order: list, kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        solve_in_order(_line([0, 1, 3, 2, 4]), 1.0, [0.0, 0.0], order, **kwargs)
