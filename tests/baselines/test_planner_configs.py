"""The configs a policy flies under and is scored against (one helper for every command line)."""

from __future__ import annotations

import pytest

import uamfleet
from uamfleet.baselines import planner_configs
from uamfleet.baselines.planner_policy import NO_SINR_DB


def test_cptsp_flies_with_one_seat_and_is_scored_with_the_scenarios_seats() -> None:
    flown, scored = planner_configs("berlin_p4", "cptsp", sinr_min_db=-5.0)
    assert (flown.seats, flown.sinr_min_db) == (1, -5.0)
    assert (scored.seats, scored.sinr_min_db) == (uamfleet.make_config("berlin_p4").seats, -5.0)
    assert scored.seats == 2


def test_straight_line_flies_blind_and_is_scored_at_the_real_threshold() -> None:
    flown, scored = planner_configs("berlin_p4", "straight", sinr_min_db=-4.0, time_limit_steps=90)
    assert flown.sinr_min_db == NO_SINR_DB and scored.sinr_min_db == -4.0
    assert flown.time_limit_steps == scored.time_limit_steps == 90


@pytest.mark.parametrize("policy", ["replan", "opt", "greedy", "random", "msha"])
def test_other_policies_fly_under_the_scored_config(policy: str) -> None:
    flown, scored = planner_configs("berlin_p4", policy, sinr_min_db=-3.0)
    assert flown is scored
    assert (scored.sinr_min_db, scored.seats) == (-3.0, uamfleet.make_config("berlin_p4").seats)
