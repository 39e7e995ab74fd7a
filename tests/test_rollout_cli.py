"""eval.rollout: every policy name of the registry's grammar flies (a search over a learned base too), a name it
cannot read is one line and exit 2, and a planner flown with SINR off is scored against the real threshold."""

from __future__ import annotations

import pytest

import uamfleet
from uamfleet.cli.rollout import Args, cli, main
from uamfleet.metrics import episode_metrics
from uamfleet.policies import available


def test_straight_line_is_scored_against_the_scenario_threshold():
    [row] = main(Args(scenario="berlin_p4", policy="straight", episodes=1))
    assert row["pr_pct"] == 100.0
    assert row["connectivity_pct"] == pytest.approx(86.0, abs=0.05)  # the paper's 86 % at -3 dB


def test_random_and_unknown_policies():
    rows = main(Args(scenario="berlin_random", policy="random", num_taxis=2, episodes=2, time_limit_steps=20))
    assert len(rows) == 2 and all(r["steps"] == 20 for r in rows)
    with pytest.raises(ValueError, match=r"unknown --policy 'dqn'; choose one of"):
        main(Args(policy="dqn"))


def test_a_search_over_the_learned_base_flies_as_the_shipped_policy_flies_itself() -> None:
    # argmax(BASE) acts as its base does: the row is the shipped policy's own flight (GreedyPolicy.fly) of the scenario
    [row] = main(Args(scenario="berlin_p4", policy="argmax(learned:source=berlin_stops)", episodes=1))
    cfg = uamfleet.make_config("berlin_p4")
    own = uamfleet.pretrained("berlin_stops").fly(cfg, seed=0)
    expected = episode_metrics(own, cfg.radio, threshold_db=cfg.sinr_min_db).as_dict()
    timed = {key for key in expected if key.startswith("decision_")}  # wall time, not the flight
    assert {k: v for k, v in row.items() if k not in timed} == {k: v for k, v in expected.items() if k not in timed}
    assert row["pr_pct"] == 100.0


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("dqn", "unknown --policy 'dqn'; choose one of 'learned', 'fleet_claims', 'cptsp',"),
        ("hedge(dqn)", "unknown policy 'dqn'; the registered policies are learned, fleet_claims, cptsp,"),
        ("replan:beem=3", "--policy 'replan:beem=3': policy 'replan' has no option 'beem'; its options are: beam,"),
    ],
)
def test_a_name_the_registry_cannot_read_is_one_line_and_exit_2(name: str, message: str, capsys) -> None:
    assert cli(["--policy", name, "--episodes", "1"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("uamfleet-rollout: error: "), err
    assert message in err
    if name == "dqn":
        assert all(repr(known) in err for known in available())


def test_a_learned_policy_that_cannot_read_the_world_says_so_in_one_line(capsys) -> None:
    # the shipped fleet policy takes the hover action, which berlin_p4 lacks
    assert cli(["--policy", "learned:source=berlin_fleet", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--policy 'learned:source=berlin_fleet' cannot fly berlin_p4" in err, err
    assert "hover_action=True" in err
