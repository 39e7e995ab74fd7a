"""Greedy decoding in which an idle taxi stays in place (uamfleet/rl/idle_wait.py, ``learned:idle_wait=true``):
on observations set by hand, and flown on a Munich training instance where the taxi is idle, the idle steps found
from the trajectory's own events (not from the rule's reading of the observation)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.rl.test_loop_guard import EAST, NORTH, WEST, observation, preferring
from uamfleet.cli import benchmark
from uamfleet.instances import make_instance
from uamfleet.policies import make_named
from uamfleet.rl.checkpoint import pretrained_path
from uamfleet.rl.idle_wait import IdleWait
from uamfleet.rollout import Trajectory, fly
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS


def forbidding(*headings: int) -> np.ndarray:
    allowed = np.ones(NUM_HEADINGS, np.int8)
    allowed[list(headings)] = 0
    return allowed


def test_an_idle_taxi_asks_for_the_first_forbidden_heading() -> None:
    """Nobody on board, no request waiting, headings 3 and 9 forbidden: the taxi asks for 3 (it stays), as replan's
    wait does; the count of waits says so."""
    rule = IdleWait()
    idle = observation((0.5, 0.5), (0.5, 0.5), 0.0, waiting=0, allowed=forbidding(9, 3))
    assert rule.choose(idle, preferring(EAST)).tolist() == [3]
    assert rule.waits == 1


@pytest.mark.parametrize("waiting, riding", [(1, 0), (0, 1)])
def test_a_taxi_with_a_request_waiting_or_a_rider_flies_its_greedy_heading(waiting: int, riding: int) -> None:
    busy = observation((0.5, 0.5), (0.5, 0.5), 0.0, waiting=waiting, riding=riding, allowed=forbidding(3))
    rule = IdleWait()
    assert rule.choose(busy, preferring(NORTH)).tolist() == [NORTH]
    assert rule.waits == 0


def test_an_idle_taxi_with_every_heading_allowed_flies_as_before() -> None:
    idle = observation((0.5, 0.5), (0.5, 0.5), 0.0, waiting=0)
    assert IdleWait().choose(idle, preferring(WEST)).tolist() == [WEST]


def test_an_idle_taxi_of_a_network_with_the_hover_hovers() -> None:
    idle = observation((0.5, 0.5), (0.5, 0.5), 0.0, waiting=0)
    assert IdleWait().choose(idle, preferring(WEST, columns=NUM_HEADINGS + 1)).tolist() == [HOVER_ACTION]


def idle_before(traj: Trajectory) -> np.ndarray:
    """[T] bool from the trajectory's events: before step t nobody is on board and every released request has
    been delivered."""
    picked = np.zeros(len(traj.pax_exists), bool)
    delivered = np.zeros(len(traj.pax_exists), bool)
    out = []
    for t, ev in enumerate(traj.events):
        released = traj.pax_exists & (traj.release_step <= t)
        out.append(not ((picked & ~delivered).any() or (released & ~picked).any()))
        picked |= ev.picked_up[0]
        delivered |= ev.dropped_off[0]
    return np.array(out)


class MaskRecorder:
    """A policy that passes every call on to ``inner`` and keeps each step's action mask."""

    def __init__(self, inner: object) -> None:
        self.inner, self.masks = inner, []
        self.spec = inner.spec  # type: ignore[attr-defined]

    def reset(self, sim: object) -> None:
        self.inner.reset(sim)  # type: ignore[attr-defined]

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        self.masks.append(obs["action_mask"][0, 0].astype(bool))
        return self.inner.act(obs)  # type: ignore[attr-defined]


def test_the_shipped_policy_stays_while_idle_and_flies_as_before_until_then() -> None:
    """Munich training instance 5 (5 requests released at steps 0, 1, 20, 21 and 37 on a map 12 moves across):
    plain, the shipped policy flies on every step; with idle_wait it stays on every idle step where a heading is
    forbidden (4 here), flies the same moves as the plain policy until its first idle step, and flies less in all
    (6,000 m against 6,400 m when written)."""
    cfg = make_instance("munich", 5, max_passengers=6)
    plain = fly(cfg, make_named("learned:source=berlin"))
    recorder = MaskRecorder(make_named("learned:source=berlin,idle_wait=true"))
    waiting = fly(cfg, recorder)
    idle = idle_before(waiting)
    can_stay = idle & ~np.array(recorder.masks).all(-1)
    assert can_stay.sum() >= 2
    moved = waiting.stacked("moved")[:, 0]
    assert not moved[can_stay].any() and moved[~idle].all()
    first = int(np.argmax(idle))
    assert idle_before(plain)[first]
    np.testing.assert_array_equal(plain.positions_m[0, : first + 1], waiting.positions_m[0, : first + 1])
    assert plain.stacked("moved")[:, 0].all()  # without the rule the taxi never stays
    assert waiting.episode["service_rate"] == plain.episode["service_rate"] == 1.0
    assert waiting.episode["distance_m"] < plain.episode["distance_m"]


def test_the_benchmark_flies_learned_with_options_only_beside_a_checkpoint(tmp_path) -> None:
    out = tmp_path / "idle.csv"
    args = benchmark.Args(map="munich", split="train", count=1, jobs=1, methods=("learned:idle_wait=true",),
                          checkpoint=None, out_csv=out)  # fmt: skip
    with pytest.raises(ValueError, match=r"learned:<options> \(e\.g\. learned:idle_wait=true\)"):
        benchmark.check_args(args)
    given = benchmark.Args(map="munich", split="train", count=1, jobs=1, methods=("learned:idle_wait=true",),
                           checkpoint=pretrained_path("berlin"), out_csv=out)  # fmt: skip
    assert len(benchmark.check_args(given)) == 1  # one instance selected, nothing refused
