"""``FinishWithSearch`` (uamfleet/baselines/finish.py): the wrapped policy until the demand model says no request
can come, then one search flown to the end. Checked against the wrapped policy's own flight (identical until the
switch), ``replan`` with the same search (identical when everything is known at the start), the plan's promised
moves, and a hidden request the switch must not count."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

from uamfleet.baselines.finish import FinishWithSearch, no_request_can_come
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.config import Request
from uamfleet.instances import FAMILIES
from uamfleet.rollout import fly

OPEN_7 = "\n".join(["......."] * 7)
REQUESTS = (
    Request(0, (150.0, 450.0), (550.0, 450.0)),
    Request(3, (650.0, 50.0), (50.0, 650.0)),
    Request(6, (350.0, 650.0), (650.0, 350.0)),
)


class FirstAllowed:
    """A deliberately poor policy: the lowest allowed heading, every step (it never finishes a tour alone)."""

    def reset(self, env) -> None:  # type: ignore[no-untyped-def]
        self.env = env

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return np.array([[int(np.argmax(obs["action_mask"][0, 0] > 0))]])


def _cfg(requests=REQUESTS):  # type: ignore[no-untyped-def]
    return small_config(OPEN_7, requests=requests, time_limit_steps=80)


def test_the_switch_rule_by_hand() -> None:
    assert not no_request_can_come(released=2, t=39, window_steps=40, max_requests=6)
    assert no_request_can_come(released=2, t=40, window_steps=40, max_requests=6)  # a release at 40 is seen at 40
    assert no_request_can_come(released=6, t=0, window_steps=40, max_requests=6)
    berlin = FinishWithSearch.of_family(FirstAllowed(), "berlin", slot_s=3.0)
    assert (berlin.window_steps, berlin.max_requests) == (40, FAMILIES["berlin"].max_passengers)


def test_it_flies_the_policy_until_the_window_closes_then_the_plan_it_promised() -> None:
    cfg, window = _cfg(), 8
    alone = fly(cfg, FirstAllowed())
    finisher = FinishWithSearch(FirstAllowed(), window_steps=window, max_requests=6, beam=16)
    traj = fly(cfg, finisher)
    moved = traj.stacked("moved")[:, 0]
    np.testing.assert_array_equal(traj.stacked("actions")[:window, 0], alone.stacked("actions")[:window, 0])
    np.testing.assert_allclose(traj.positions_m[0, : window + 1], alone.positions_m[0, : window + 1])
    assert [step for step, *_ in finisher.solves] == [window]  # one search, at the first step nothing can come
    _, promised, cpu_s, wall_s = finisher.solves[0]
    assert traj.terminated and int(traj.stacked("dropoffs").sum()) == len(REQUESTS)
    assert int(moved[window:].sum()) == promised  # the plan flew the moves it promised
    assert cpu_s >= 0.0 and wall_s >= 0.0
    assert not alone.terminated  # the wrapped policy alone never delivers: the search finished the work


def test_with_everything_known_at_the_start_it_is_replan_with_the_same_search() -> None:
    known = tuple(Request(0, r.origin_m, r.destination_m) for r in REQUESTS)
    cfg = _cfg(known)
    finisher = FinishWithSearch(FirstAllowed(), window_steps=40, max_requests=len(known), beam=16)
    replan = StepPlannerPolicy("replan", [SearchSettings(beam=16, rank_slack=0.5)])
    ours, theirs = fly(cfg, finisher), fly(cfg, replan)
    assert finisher.solves[0][0] == 0
    np.testing.assert_allclose(ours.positions_m, theirs.positions_m)
    assert ours.episode["distance_m"] == theirs.episode["distance_m"]


def test_a_hidden_request_is_not_counted_by_the_switch() -> None:
    """At most 2 requests and 2 in the instance, the second released at step 3: the count reaches the most only
    when it is released, so the search runs at step 3 (counting the hidden row would switch at step 0). The
    plan is then made over both requests."""
    two = REQUESTS[:2]
    finisher = FinishWithSearch(FirstAllowed(), window_steps=40, max_requests=2, beam=16)
    traj = fly(_cfg(two), finisher)
    assert [step for step, *_ in finisher.solves] == [3]
    assert traj.terminated and int(traj.stacked("dropoffs").sum()) == 2


@pytest.mark.parametrize(("window", "most", "beam"), [(-1, 6, 16), (40, 0, 16), (40, 6, 0)])
def test_bad_settings_are_refused_with_the_fix(window: int, most: int, beam: int) -> None:
    with pytest.raises(ValueError, match=r"e\.g\. FinishWithSearch\.of_family"):
        FinishWithSearch(FirstAllowed(), window_steps=window, max_requests=most, beam=beam)
