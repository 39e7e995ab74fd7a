"""Scenario / demand -> initial state: fixed instances, random Poisson demand, random feasible starts.

Randomness comes only from the ``np.random.Generator`` passed in (one per env). The rules: docs/rules.md
("Feasibility rules", "Release and pick-up").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from uamfleet.config import Request, separation_room_bound
from uamfleet.sim.world import World
from uamfleet.types import HIDDEN, NUM_HEADINGS, WAITING, FleetState


class InfeasibleInstanceError(ValueError):
    """A start or stop lies outside the map, in a block below the threshold, or out of reach of every start."""


def validate_instance(world: World, starts_m: np.ndarray | None, requests: Sequence[Request]) -> None:
    """Raise :class:`InfeasibleInstanceError` naming the point, the threshold and the fix.

    Reachability is judged on 8-connected flyable blocks (SINR block map at the threshold): a stop is
    reachable when its block lies in the same component as some taxi's start block. With ``starts_m=None``
    (starts drawn per episode) only each stop's own block is checked.
    """
    thr = world.threshold_db
    fix = "move the point, or lower sinr_min_db"
    for a, start in enumerate(np.asarray(starts_m if starts_m is not None else np.empty((0, 2)), dtype=float)):
        _check_point(world, start, f"start of taxi {a}", fix)
        if not world.action_mask(start).any():
            raise InfeasibleInstanceError(
                f"start of taxi {a} at {tuple(start.tolist())} has no allowed move at sinr_min_db={thr} dB: every "
                f"heading leaves the map or enters a block below the threshold; {fix}."
            )
    start_components = None if starts_m is None else set(world.component_of(np.asarray(starts_m, float)).tolist())
    for i, req in enumerate(requests):
        for what, point in (("origin", req.origin_m), ("destination", req.destination_m)):
            label = f"{what} of passenger {i} (P{i + 1})"
            p = np.asarray(point, dtype=float)
            _check_point(world, p, label, fix)
            if start_components is not None and int(world.component_of(p)) not in start_components:
                raise InfeasibleInstanceError(
                    f"{label} at {point} is unreachable from the start(s) at sinr_min_db={thr} dB: no path of "
                    f"flyable {world.blocks.block_m:g} m blocks connects them; lower sinr_min_db or move it."
                )


def _check_point(world: World, point: np.ndarray, label: str, fix: str) -> None:
    side = world.side_m
    if not bool(world.in_domain(point)):
        raise InfeasibleInstanceError(
            f"{label} at {tuple(point.tolist())} lies outside the map [0, {side:g}] x [0, {side:g}] m "
            f"({world.radio.label}); use world-frame metres inside it."
        )
    if not bool(world.point_feasible(point)):
        sinr = float(world.blocks.sinr_at(point))
        raise InfeasibleInstanceError(
            f"{label} at {tuple(point.tolist())} is in a block with SINR {sinr:.2f} dB, below "
            f"sinr_min_db={world.threshold_db} dB ({world.cfg.feasibility} rule); {fix}."
        )


# ---- room to separate ----------------------------------------------------------------------------------

_MAX_ROOM_GRID = 4_000_000
"""Cells of the largest grid :func:`separation_room` marks (a separation far below the block size: its bound is
then the sum over the rectangles instead, looser but never below the true room)."""


_RASTER_TILES = 128
"""Raster cells are grouped into at most this many tiles per side for :func:`check_separation_room`."""


def separation_room(rects: np.ndarray, min_separation_m: float) -> int:
    """At most how many points of the union of closed rectangles ``rects`` ([R, 4]: x0, y0, x1, y1) can lie
    pairwise ``min_separation_m`` apart: :func:`~uamfleet.config.separation_room_bound` of its bounding box and
    convex hull, and at most one point per half-open square of side ``min_separation_m / sqrt(2)`` that the union
    touches (two points in one are closer than its diagonal; the fewest over four placements of the squares'
    grid). An upper bound: a union past it certainly has no room."""
    if not len(rects):
        return 0
    lo, hi = rects[:, :2].min(axis=0), rects[:, 2:].max(axis=0)
    width, height = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    corners = np.concatenate([rects[:, [0, 1]], rects[:, [2, 1]], rects[:, [0, 3]], rects[:, [2, 3]]])
    try:
        hull = ConvexHull(corners)
        best = separation_room_bound(width, height, min_separation_m, hull.volume, hull.area)  # 2-D: area, perimeter
    except QhullError:  # a union of zero area (blocks cut to a map edge): the bounding box alone
        best = separation_room_bound(width, height, min_separation_m)
    cell = min_separation_m / np.sqrt(2.0)
    rects = rects + np.array([-1e-6, -1e-6, 1e-6, 1e-6])  # a micrometre more: rounding never drops a square
    for ox, oy in ((0.0, 0.0), (cell / 2, 0.0), (0.0, cell / 2), (cell / 2, cell / 2)):
        i0, i1 = np.floor((rects[:, 0] - ox) / cell), np.floor((rects[:, 2] - ox) / cell)
        j0, j1 = np.floor((rects[:, 1] - oy) / cell), np.floor((rects[:, 3] - oy) / cell)
        lo_i, lo_j = i0.min(), j0.min()
        ni, nj = int(i1.max() - lo_i) + 1, int(j1.max() - lo_j) + 1
        if ni * nj > _MAX_ROOM_GRID:
            count = int(((i1 - i0 + 1) * (j1 - j0 + 1)).sum())
        else:  # mark the touched squares: a 2-D difference array, then its running sums
            i0, i1, j0, j1 = (
                np.asarray(v - lo, np.int64) for v, lo in ((i0, lo_i), (i1, lo_i), (j0, lo_j), (j1, lo_j))
            )
            diff = np.zeros((ni + 1, nj + 1), np.int64)
            for di, dj, sign, ii, jj in ((0, 0, 1, i0, j0), (1, 0, -1, i1, j0), (0, 1, -1, i0, j1), (1, 1, 1, i1, j1)):
                np.add.at(diff, (ii + di, jj + dj), sign)
            count = int((diff.cumsum(0).cumsum(1) > 0).sum())
        best = min(best, count)
    return best


def _flyable_rects(world: World, blocks: np.ndarray | None = None) -> np.ndarray:
    """[R, 4] closed rectangles (x0, y0, x1, y1) covering every point a taxi may be at: the flyable blocks
    (``blocks``: a bool mask of some of them) under ``endpoint_block``; under ``segment_raster`` the tiles of
    raster cells (each point's nearest) with a cell at the threshold; cut to the map."""
    side = world.side_m
    if world.cfg.feasibility == "endpoint_block":
        b = world.blocks.block_m
        bx, by = np.nonzero(world.block_ok if blocks is None else blocks)
        lo = np.stack([bx * b, by * b], axis=-1)
        hi = lo + b
    else:  # raster cells, in tiles of f x f cells (a tile with one flyable cell counts whole: a larger area)
        radio = world.radio
        with np.errstate(invalid="ignore"):
            ok = np.asarray(radio.sinr_db) >= world.threshold_db
        f = -(-max(ok.shape) // _RASTER_TILES)
        padded = np.zeros((-(-ok.shape[0] // f) * f, -(-ok.shape[1] // f) * f), bool)
        padded[: ok.shape[0], : ok.shape[1]] = ok
        tx, ty = np.nonzero(padded.reshape(padded.shape[0] // f, f, padded.shape[1] // f, f).any(axis=(1, 3)))
        res = radio.resolution_m
        lo = np.asarray(radio.origin_m, float) - res / 2 + np.stack([tx, ty], axis=-1) * f * res
        hi = lo + f * res
    rects = np.concatenate([np.clip(lo, 0.0, side), np.clip(hi, 0.0, side)], axis=-1).astype(float)
    return rects.reshape(-1, 4)


def check_separation_room(world: World, starts_m: np.ndarray | None, sites: np.ndarray | None) -> None:
    """Under the separation shield, refuse taxis that could never be ``min_separation_m`` apart on the flyable
    area: raise :class:`InfeasibleInstanceError` naming the taxis, the room and the fix.

    Taxis in one 8-connected area of flyable blocks stay in it where a move cannot leap a block (``endpoint_block``
    with ``block_m >= step_m``): fixed starts are counted per area, random starts (drawn from ``sites``, the largest
    area) all in that one. Otherwise all taxis count against the whole flyable area. The room is the upper bound
    of :func:`separation_room`, so a refusal is certain; a fleet within it may still be too tight to separate."""
    cfg = world.cfg
    sep, taxis = cfg.min_separation_m, cfg.num_taxis
    if cfg.separation != "shield" or taxis < 2 or sep <= 0:
        return
    per_area = cfg.feasibility == "endpoint_block" and world.blocks.block_m >= cfg.step_m
    if not per_area:
        groups = [(np.arange(taxis), None)]
    elif starts_m is not None:
        labels = world.component_of(np.asarray(starts_m, float))
        groups = [(np.flatnonzero(labels == lab), world.components == lab) for lab in np.unique(labels)]
    else:
        assert sites is not None
        groups = [(np.arange(taxis), world.components == world.component_of(sites[:1])[0])]
    for members, area in groups:
        if len(members) < 2:
            continue
        room = separation_room(_flyable_rects(world, area), sep)
        if len(members) > room:
            where = "the flyable area" if area is None else "one flyable area"
            if starts_m is None:
                who = f"the {taxis} taxis (random starts)"
            else:
                who = (
                    f"taxis {members.tolist()} (starts from {tuple(np.asarray(starts_m, float)[members[0]].tolist())})"
                )
            raise InfeasibleInstanceError(
                f"{who} cannot all be min_separation_m={sep:g} m apart in {where} of {world.radio.label} at "
                f"sinr_min_db={world.threshold_db} dB: it has room for at most {room} taxi(s) that far apart, so the "
                "separation shield could never separate them; lower min_separation_m, fly fewer taxis, start them in "
                "a larger flyable area, or use separation='none'."
            )


# ---- random instances ---------------------------------------------------------------------------------


def flyable_sites(world: World) -> np.ndarray:
    """[S, 2] block centres of the largest component of flyable blocks (where random stops are drawn)."""
    if world.num_components == 0:
        raise InfeasibleInstanceError(
            f"no block of {world.radio.label} reaches sinr_min_db={world.threshold_db} dB; lower the threshold."
        )
    sizes = np.bincount(world.components.ravel())[1:]
    largest = int(np.argmax(sizes)) + 1
    bx, by = np.nonzero(world.components == largest)
    b = world.blocks.block_m
    centres = np.stack([(bx + 0.5) * b, (by + 0.5) * b], axis=-1)
    centres = np.minimum(centres, world.side_m - 1e-6)
    return centres[world.point_feasible(centres) & world.action_mask(centres).any(-1)]


def sample_starts(world: World, rng: np.random.Generator, sites: np.ndarray) -> np.ndarray:
    num_taxis = world.cfg.num_taxis
    idx = rng.choice(len(sites), size=num_taxis, replace=len(sites) < num_taxis)
    return sites[idx]


class TripEnds:
    """Where a trip from each of ``points`` may end: the points at least ``min_trip_m`` away (all others when
    none is that far). Each origin's list is computed on first use and kept (an episode reset draws a dozen
    trips; recomputing the distances to every site each time was most of an autoreset's cost)."""

    def __init__(self, points: np.ndarray, min_trip_m: float) -> None:
        self.points = points
        self.min_trip_m = min_trip_m
        self._ends: dict[int, np.ndarray] = {}

    def __call__(self, o: int) -> np.ndarray:
        ends = self._ends.get(o)
        if ends is None:
            points = self.points
            far = np.linalg.norm(points - points[o], axis=-1) >= self.min_trip_m
            far[o] = False  # with min_trip_m = 0 the origin itself is "far enough": a ride that goes nowhere
            ends = np.nonzero(far)[0] if far.any() else np.nonzero(np.arange(len(points)) != o)[0]
            self._ends[o] = ends
        return ends


def sample_requests(
    world: World, rng: np.random.Generator, sites: np.ndarray, trip_ends: TripEnds | None = None
) -> list[Request]:
    """Release steps by ``DemandConfig.arrivals`` (Poisson: ``num_initial`` at step 0, then rate
    ``rate_per_step`` until ``horizon_steps``; uniform: see :class:`~uamfleet.config.DemandConfig`), then
    each request's origin and destination.

    ``trip_ends`` (for the same points: the vertiports if any, else ``sites``) only saves time."""
    demand = world.cfg.demand
    if demand.arrivals == "uniform":
        count = int(rng.integers(demand.min_requests, demand.max_requests + 1))
        initial = min(demand.num_initial, count)
        later = rng.integers(0, demand.horizon_steps + 1, size=count - initial)
        release = [0] * initial + sorted(int(t) for t in later)
    else:
        release = [0] * demand.num_initial
        t = 0.0
        while demand.rate_per_step > 0 and len(release) < demand.max_requests:
            t += rng.exponential(1.0 / demand.rate_per_step)
            if t > demand.horizon_steps:
                break
            release.append(max(1, int(np.ceil(t))))
    if not release:  # an episode needs at least one request
        release = [0]
    points = np.asarray(demand.vertiports, dtype=float) if demand.vertiports else sites
    if trip_ends is None:
        trip_ends = TripEnds(points, demand.min_trip_m)
    requests = []
    for step in release:
        o = int(rng.integers(len(points)))
        ends = trip_ends(o)
        d = int(ends[rng.integers(len(ends))])  # what rng.choice(ends) draws, without its argument handling
        requests.append(Request(step, tuple(points[o]), tuple(points[d])))
    return requests


# ---- state allocation and reset ---------------------------------------------------------------------------


PAX_NONE: dict[str, int] = {"pax_taxi": -1, "pax_pickup_step": -1, "pax_dropoff_step": -1}
"""The value of an empty passenger row in the ``pax_*`` fields that are not 0 there (no taxi, no step yet)."""


def allocate_state(world: World, num_envs: int) -> FleetState:
    cfg = world.cfg
    E, A, P, H, k = num_envs, cfg.num_taxis, cfg.num_passengers, cfg.history_len, cfg.patch_size
    nbx, nby = world.num_blocks
    return FleetState(
        t=np.zeros(E, np.int64),
        pos_m=np.zeros((E, A, 2)),
        free_seats=np.zeros((E, A), np.int64),
        history_m=np.zeros((E, A, H, 2)),
        history_seats=np.zeros((E, A, H), np.int64),
        visits=np.zeros((E, A, nbx + k, nby + k), np.int32),
        distance_m=np.zeros((E, A)),
        action_mask=np.zeros((E, A, NUM_HEADINGS), bool),
        pax_exists=np.zeros((E, P), bool),
        pax_release=np.zeros((E, P), np.int64),
        pax_origin_m=np.zeros((E, P, 2)),
        pax_dest_m=np.zeros((E, P, 2)),
        pax_status=np.zeros((E, P), np.int8),
        pax_taxi=np.full((E, P), PAX_NONE["pax_taxi"], np.int64),
        pax_pickup_step=np.full((E, P), PAX_NONE["pax_pickup_step"], np.int64),
        pax_dropoff_step=np.full((E, P), PAX_NONE["pax_dropoff_step"], np.int64),
        stop_pair_m=np.full((E, 2 * P, 2 * P) if cfg.stop_features else (E, 0, 0), np.nan),
        stop_tour_key=np.full((E, A), -1, np.int64),
        stop_tour_m=np.full((E, A, 2 * P if cfg.stop_features else 0), np.nan),
    )


def pad_passengers(state: FleetState, rows: int) -> FleetState:
    """A copy of ``state`` on a passenger axis of ``rows`` (at least its own): the rows added are empty, as
    :func:`allocate_state` makes them (no passenger, no stop distances known), and each taxi's cached tours are
    marked stale (their key -1) because their stop axis grew; every other field is copied."""
    P = state.pax_exists.shape[1]
    if rows < P:
        raise ValueError(f"rows={rows} is fewer than the state's {P} passenger rows; give at least {P}.")
    if rows == P:
        return state.copy()
    E, A = state.pos_m.shape[:2]

    def grown(name: str, fill: float | int) -> np.ndarray:
        old = getattr(state, name)
        out = np.full((E, rows, *old.shape[2:]), fill, old.dtype)
        out[:, :P] = old
        return out

    fields = {name: np.array(getattr(state, name)) for name in FleetState._fields}
    for name in FleetState._fields:
        if name.startswith("pax_"):  # [E, P, ...]: the passenger rows
            fields[name] = grown(name, PAX_NONE.get(name, 0))
    if state.stop_pair_m.shape[1]:  # with the stop features: [E, 2P, 2P] and [E, A, 2P]
        pairs = np.full((E, 2 * rows, 2 * rows), np.nan)
        pairs[:, : 2 * P, : 2 * P] = state.stop_pair_m
        fields["stop_pair_m"] = pairs
        fields["stop_tour_m"] = np.full((E, A, 2 * rows), np.nan)
        fields["stop_tour_key"] = np.full((E, A), -1, np.int64)
    return FleetState(**fields)


def write_instance(state: FleetState, e: int, world: World, starts_m: np.ndarray, requests: Sequence[Request]) -> None:
    """Reset env ``e`` of ``state`` in place to the given instance (validated by the caller)."""
    cfg = world.cfg
    n = len(requests)
    if n > cfg.num_passengers:
        raise ValueError(f"{n} requests do not fit max_passengers={cfg.num_passengers}; raise max_passengers.")
    starts = np.asarray(starts_m, dtype=float).reshape(cfg.num_taxis, 2)
    state.t[e] = 0
    state.pos_m[e] = starts
    state.free_seats[e] = cfg.seats
    state.history_m[e] = starts[:, None, :]
    state.history_seats[e] = cfg.seats
    state.visits[e] = 0
    bx, by = world.block_index(starts)
    state.visits[e, np.arange(cfg.num_taxis), bx + world.patch_lo, by + world.patch_lo] += 1
    state.distance_m[e] = 0.0
    state.action_mask[e] = world.action_mask(starts)
    state.pax_exists[e] = np.arange(cfg.num_passengers) < n
    state.pax_release[e] = 0
    state.pax_origin_m[e] = 0.0
    state.pax_dest_m[e] = 0.0
    if n:
        state.pax_release[e, :n] = [r.release_step for r in requests]
        state.pax_origin_m[e, :n] = [r.origin_m for r in requests]
        state.pax_dest_m[e, :n] = [r.destination_m for r in requests]
    state.pax_status[e] = np.where(state.pax_exists[e] & (state.pax_release[e] <= 0), WAITING, HIDDEN)
    state.pax_taxi[e] = -1
    state.pax_pickup_step[e] = -1
    state.pax_dropoff_step[e] = -1
    state.stop_pair_m[e] = np.nan  # new stops: distances between them are looked up again
    state.stop_tour_key[e] = -1


class InstanceSource:
    """Where each episode's instance comes from: the config's fixed one, or drawn from the demand model."""

    def __init__(self, world: World) -> None:
        cfg = world.cfg
        self.world = world
        self._sites: np.ndarray | None = None
        self._trip_ends: TripEnds | None = None
        self.fixed_starts = None if cfg.starts_m is None else np.asarray(cfg.starts_m, dtype=float)
        self.fixed_requests = cfg.requests
        if self.fixed_starts is not None or self.fixed_requests is not None:
            # Validate what is fixed once; random parts are drawn from flyable sites by construction.
            validate_instance(world, self.fixed_starts, self.fixed_requests or ())

        self._check_sites()
        self._check_vertiports()
        check_separation_room(world, self.fixed_starts, None if self.fixed_starts is not None else self.sites)

    def _check_sites(self) -> None:
        """Random parts are drawn from the flyable sites: too few of them would fail inside NumPy at the first
        reset, so say so now."""
        world, cfg = self.world, self.world.cfg
        needs_sites = {"random starts": self.fixed_starts is None, "random stops": not self.fixed_requests}
        needs_sites["random stops"] &= not cfg.demand.vertiports
        if not any(needs_sites.values()):
            return
        need = 2 if needs_sites["random stops"] else 1
        if len(self.sites) < need:
            what = " and ".join(k for k, v in needs_sites.items() if v)
            raise InfeasibleInstanceError(
                f"{what} need {need} flyable block(s) with an allowed move on {world.radio.label} at "
                f"sinr_min_db={world.threshold_db} dB, found {len(self.sites)}; lower sinr_min_db, or give "
                "starts_m / requests / DemandConfig.vertiports."
            )

    def _check_vertiports(self) -> None:
        """Every vertiport of the random demand is flyable and, with random starts, in the starts' component."""
        world, cfg = self.world, self.world.cfg
        ports = np.asarray(cfg.demand.vertiports if cfg.requests is None else (), float).reshape(-1, 2)
        for i, port in enumerate(ports):
            _check_point(world, port, f"vertiport {i}", "move the vertiport, or lower sinr_min_db")
        if len(ports) and self.fixed_starts is None:
            starts_area = world.component_of(self.sites[:1])[0]  # random starts come from this component
            for i, label in enumerate(world.component_of(ports)):
                if label != starts_area:
                    raise InfeasibleInstanceError(
                        f"vertiport {i} at {tuple(ports[i].tolist())} is unreachable from the flyable area where "
                        f"taxis start at sinr_min_db={world.threshold_db} dB; move it or lower sinr_min_db."
                    )

    @property
    def sites(self) -> np.ndarray:
        if self._sites is None:
            self._sites = flyable_sites(self.world)
        return self._sites

    def draw(self, rng: np.random.Generator) -> tuple[np.ndarray, list[Request]]:
        starts = self.fixed_starts if self.fixed_starts is not None else sample_starts(self.world, rng, self.sites)
        if self.fixed_requests is not None:
            requests = list(self.fixed_requests)
        else:
            if self._trip_ends is None:
                demand = self.world.cfg.demand
                points = np.asarray(demand.vertiports, dtype=float) if demand.vertiports else self.sites
                self._trip_ends = TripEnds(points, demand.min_trip_m)
            requests = sample_requests(self.world, rng, self.sites, self._trip_ends)
        return starts, requests
