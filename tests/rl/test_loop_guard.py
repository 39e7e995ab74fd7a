"""The loop guard of greedy decoding (uamfleet/rl/loop_guard.py, docs/rules.md "Greedy decoding of a trained
policy"): on drawn observations whose positions and logits are set by hand, and on the test instance where the
shipped policy flew two headings back and forth until the time limit."""

from __future__ import annotations

import numpy as np
import pytest

import uamfleet
from uamfleet.config import heading_vectors
from uamfleet.instances import instance_for_policy
from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.types import NUM_HEADINGS, PASSENGER_FEATURES

STEP = 0.1  # step_m / side_m of the drawn scenes
UNIT = heading_vectors()
EAST, NORTH, WEST, SOUTH = (
    int(np.argmin(np.linalg.norm(UNIT - v, axis=1))) for v in ((1, 0), (0, 1), (-1, 0), (0, -1))
)


def observation(pos, previous, clock, seats=1.0, waiting=1, riding=0, others=0, allowed=None) -> dict[str, np.ndarray]:
    """One taxi's observation [1, 1, ...] with what the guard reads: position, the last move, clock, seats,
    ``waiting`` released requests and ``riding`` ones on board (one row each), and ``others`` other taxis."""
    pax = np.zeros((1, 1, 3, len(PASSENGER_FEATURES)), np.float32)
    pax[0, 0, :waiting, PASSENGER_FEATURES.index("waiting")] = 1
    pax[0, 0, waiting : waiting + riding, PASSENGER_FEATURES.index("on_board_self")] = 1
    mask = np.zeros((1, 1, 3), np.int8)
    mask[0, 0, : waiting + riding] = 1
    others_mask = np.zeros((1, 1, 3), np.int8)
    others_mask[0, 0, :others] = 1
    history = np.zeros((1, 1, 3, 3), np.float32)
    history[0, 0, 0, :2] = np.subtract(previous, pos)
    action_mask = np.ones((1, 1, NUM_HEADINGS), np.int8) if allowed is None else allowed.reshape(1, 1, -1)
    me = np.array([[[pos[0], pos[1], seats, clock]]], np.float32)
    return {
        "self": me, "history": history, "passengers": pax, "passenger_mask": mask, "action_mask": action_mask,
        "others_mask": others_mask,
    }  # fmt: skip


def preferring(*headings: int, columns: int = NUM_HEADINGS) -> np.ndarray:
    """Logits [1, columns]: the given headings first, in that order of preference, every other one far below."""
    logits = np.full((1, columns), -10.0)
    for rank, h in enumerate(headings):
        logits[0, h] = 5.0 - rank
    return logits


def fly_east_then(guard: LoopGuard, second_obs: dict[str, np.ndarray], logits: np.ndarray) -> int:
    """The guard sees the taxi at the start, flies it east, then asks for a decision at ``second_obs``."""
    start = (0.5, 0.5)
    assert guard.choose(observation(start, start, 0.0), preferring(EAST))[0] == EAST
    return int(guard.choose(second_obs, logits)[0])


def test_a_return_without_an_event_is_replaced_by_the_next_most_likely_heading() -> None:
    guard = LoopGuard()
    there = (0.5 + STEP, 0.5)
    assert fly_east_then(guard, observation(there, (0.5, 0.5), 0.01), preferring(WEST, NORTH)) == NORTH
    assert guard.interventions == 1


def test_a_return_after_an_event_is_flown() -> None:
    there = (0.5 + STEP, 0.5)
    picked_up = observation(there, (0.5, 0.5), 0.01, seats=0.5)  # a seat taken: the taxi's world changed
    assert fly_east_then(LoopGuard(), picked_up, preferring(WEST, NORTH)) == WEST
    released = observation(there, (0.5, 0.5), 0.01, waiting=2)  # a new request
    assert fly_east_then(LoopGuard(), released, preferring(WEST, NORTH)) == WEST


def test_a_taxi_with_nowhere_to_go_may_circle() -> None:
    """An idle lone taxi (no request known) zig-zags to wait; so may a fleet taxi without a rider or a claim."""
    there = (0.5 + STEP, 0.5)
    idle = observation(there, (0.5, 0.5), 0.01, waiting=0)
    assert fly_east_then(LoopGuard(), idle, preferring(WEST, NORTH)) == WEST
    in_a_fleet = observation(there, (0.5, 0.5), 0.01, waiting=1, others=2)
    assert fly_east_then(LoopGuard(), in_a_fleet, preferring(WEST, NORTH)) == WEST
    with_a_rider = observation(there, (0.5, 0.5), 0.01, waiting=0, riding=1, others=2)
    guard = LoopGuard()
    guard.choose(observation((0.5, 0.5), (0.5, 0.5), 0.0, waiting=0, riding=1, others=2), preferring(EAST))
    assert guard.choose(with_a_rider, preferring(WEST, NORTH))[0] == NORTH


def test_the_argmax_stays_when_every_allowed_heading_returns() -> None:
    only_west = np.zeros(NUM_HEADINGS, np.int8)
    only_west[WEST] = 1
    there = (0.5 + STEP, 0.5)
    obs = observation(there, (0.5, 0.5), 0.01, allowed=only_west)
    assert fly_east_then(LoopGuard(), obs, preferring(WEST, NORTH)) == WEST


def test_a_new_episode_forgets_the_points() -> None:
    guard = LoopGuard()
    there = (0.5 + STEP, 0.5)
    fly_east_then(guard, observation(there, (0.5, 0.5), 0.01), preferring(NORTH))
    # the clock starts again at the same point: a fresh episode, in which nothing has been visited yet
    assert guard.choose(observation(there, (0.5, 0.5), 0.0), preferring(WEST, NORTH))[0] == WEST


def test_a_hover_is_never_replaced() -> None:
    there = (0.5 + STEP, 0.5)
    hover = NUM_HEADINGS  # the hover action's column
    logits = preferring(hover, WEST, NORTH, columns=NUM_HEADINGS + 1)
    assert fly_east_then(LoopGuard(), observation(there, (0.5, 0.5), 0.01), logits) == hover


def test_a_square_is_not_closed() -> None:
    """Four moves east, north, west, south would end where the taxi started: the fourth is replaced."""
    guard = LoopGuard()
    corners = [(0.5, 0.5), (0.5 + STEP, 0.5), (0.5 + STEP, 0.5 + STEP), (0.5, 0.5 + STEP)]
    wanted = [EAST, NORTH, WEST]
    previous = corners[0]
    for k, (pos, heading) in enumerate(zip(corners[:3], wanted, strict=True)):
        assert guard.choose(observation(pos, previous, 0.01 * k), preferring(heading))[0] == heading
        previous = pos
    assert guard.choose(observation(corners[3], previous, 0.03), preferring(SOUTH, WEST))[0] == WEST


def test_rows_of_a_batch_keep_their_own_points() -> None:
    """Two envs in one batch: the taxi that returns is guarded, the one that moves on is not touched."""
    guard = LoopGuard()
    start = (0.5, 0.5)

    def batch(*rows: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}

    first = batch(observation(start, start, 0.0), observation(start, start, 0.0))
    assert guard.choose(first, np.concatenate([preferring(EAST), preferring(EAST)])).tolist() == [EAST, EAST]
    there = (0.5 + STEP, 0.5)
    second = batch(observation(there, start, 0.01), observation(there, start, 0.01))
    chosen = guard.choose(second, np.concatenate([preferring(WEST, NORTH), preferring(EAST, NORTH)]))
    assert chosen.tolist() == [NORTH, EAST]


@pytest.mark.parametrize("guarded", [True, False])
def test_a_policy_that_circled_under_segment_raster_no_longer_does(guarded: bool) -> None:
    """Berlin test instance 2000015 under ``segment_raster``: unguarded, the one-move look-ahead policy (shipped as
    "berlin" until 2026-12-02) delivered 1 of 4 and flew headings 6 and 14 back and forth until the 600-step limit
    (docs/results.md); guarded it delivers everyone."""
    policy = uamfleet.pretrained("berlin_lookahead1")
    assert policy.trained_on is not None
    cfg = instance_for_policy("berlin", 2000015, policy.trained_on.replace(feasibility="segment_raster"))
    if not guarded:
        policy.loop_guard = None
    trajectory = policy.fly(cfg)
    if guarded:
        assert trajectory.episode["service_rate"] == 1.0
        assert trajectory.num_steps < 200
    else:
        assert trajectory.episode["service_rate"] == 0.25 and trajectory.truncated
