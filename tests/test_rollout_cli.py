"""eval.rollout: every policy name flies, and a planner flown with SINR off is scored against the real threshold."""

from __future__ import annotations

import pytest

from uamfleet.cli.rollout import Args, main


def test_straight_line_is_scored_against_the_scenario_threshold():
    [row] = main(Args(scenario="berlin_p4", policy="straight", episodes=1))
    assert row["pr_pct"] == 100.0
    assert row["connectivity_pct"] == pytest.approx(86.0, abs=0.05)  # the paper's 86 % at -3 dB


def test_random_and_unknown_policies():
    rows = main(Args(scenario="berlin_random", policy="random", num_taxis=2, episodes=2, time_limit_steps=20))
    assert len(rows) == 2 and all(r["steps"] == 20 for r in rows)
    with pytest.raises(ValueError, match=r"unknown --policy 'dqn'; choose one of"):
        main(Args(policy="dqn"))
