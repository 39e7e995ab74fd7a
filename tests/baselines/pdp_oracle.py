"""Brute-force oracles for :mod:`uamfleet.baselines.sequencing`: every feasible stop sequence, enumerated.

The independent check of the DP (:func:`~uamfleet.baselines.sequencing.solve_pdp`): it shares only the
schedule arithmetic (``_advance``, ``_key``, ``_plan``), so that equal totals tie the same way in both.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from uamfleet.baselines.sequencing import DROPOFF, PICKUP, Plan, _advance, _key, _node, _plan, _Problem, _problem


def _sequences(pb: _Problem) -> Iterator[tuple[int, ...]]:
    """Every precedence- and capacity-feasible node sequence serving all active passengers (depth first)."""
    waiting = [i for i in pb.active if i not in pb.on_board]
    total = 2 * len(waiting) + len(pb.on_board)

    def extend(seq: list[int], waiting: list[int], riding: list[int]) -> Iterator[tuple[int, ...]]:
        if len(seq) == total:
            yield tuple(seq)
            return
        if len(riding) < pb.capacity:
            for i in waiting:
                seq.append(_node(i, PICKUP))
                yield from extend(seq, [w for w in waiting if w != i], [*riding, i])
                seq.pop()
        for i in riding:
            seq.append(_node(i, DROPOFF))
            yield from extend(seq, waiting, [r for r in riding if r != i])
            seq.pop()

    yield from extend([], waiting, sorted(pb.on_board))


def brute_force_pdp(
    dist_m: np.ndarray,
    speed_mps: float,
    release_s: Sequence[float],
    *,
    capacity: int = 2,
    on_board: Sequence[bool] | None = None,
    done: Sequence[bool] | None = None,
    start_s: float = 0.0,
    objective: str = "makespan",
    wait_weight: float = 0.0,
) -> Plan:
    """Same contract as :func:`solve_pdp` by enumerating every feasible sequence (a check; fine up to N = 5)."""
    pb = _problem(dist_m, speed_mps, release_s, capacity, on_board, done, start_s, objective, wait_weight)
    best_key: tuple[object, ...] | None = None
    best: tuple[int, ...] = ()
    for seq in _sequences(pb):
        t, ride, dist, last = pb.start_s, 0.0, 0.0, 0
        for node in seq:
            t, ride, dist = _advance(pb, t, ride, dist, last, node)
            last = node
        key = _key(pb, t, ride, dist, seq)
        if best_key is None or key < best_key:
            best_key, best = key, seq
    return _plan(pb, best)


def every_plan(
    dist_m: np.ndarray,
    speed_mps: float,
    release_s: Sequence[float],
    *,
    capacity: int = 2,
    on_board: Sequence[bool] | None = None,
    done: Sequence[bool] | None = None,
    start_s: float = 0.0,
) -> list[Plan]:
    """The plan of every feasible sequence (its plain totals: time, distance, ride, wait)."""
    pb = _problem(dist_m, speed_mps, release_s, capacity, on_board, done, start_s, "makespan")
    return [_plan(pb, seq) for seq in _sequences(pb)]


def count_feasible_sequences(n: int, capacity: int) -> int:
    """Number of precedence- and capacity-feasible sequences for n waiting passengers (N!·3^(N−1) for 2 seats)."""
    if int(n) != n or n < 0:
        raise ValueError(f"n must be an integer >= 0 passengers, got {n!r}")
    size = 1 + 2 * int(n)
    pb = _problem(np.zeros((size, size)), 1.0, [0.0] * int(n), capacity, None, None, 0.0, "makespan")
    return sum(1 for _ in _sequences(pb))
