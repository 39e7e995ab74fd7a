"""The planners in a world with the hover action (16): they never choose it, so a hover world's rows of ``replan``
and ``best_known`` are those of the same instance without it (the yardsticks of a hedge that waits by hovering)."""

from __future__ import annotations

import numpy as np
import pytest

from uamfleet.instances import make_instance, split_seeds
from uamfleet.policies import make
from uamfleet.policies.registry import PolicyNameError
from uamfleet.rollout import fly
from uamfleet.types import HOVER_ACTION


@pytest.mark.parametrize("seed", split_seeds("validation", 3))
@pytest.mark.parametrize(("name", "options"), [("replan", {"beam": 16}), ("best_known", {"beams": (16,)})])
def test_a_planner_flies_a_hover_world_as_the_world_without_it(seed: int, name: str, options: dict) -> None:
    cfg = make_instance("berlin", seed)
    plain = fly(cfg, make(name, **options))
    hovering = fly(cfg.replace(hover_action=True), make(name, **options))
    assert not (hovering.stacked("actions") == HOVER_ACTION).any()
    np.testing.assert_array_equal(plain.positions_m, hovering.positions_m)
    assert plain.num_steps == hovering.num_steps and plain.terminated and hovering.terminated


def test_the_hedge_option_names_its_wait_actions() -> None:
    with pytest.raises(PolicyNameError, match="wait_action='sit' is unknown; choose one of"):
        make("hedge", wait_action="sit")
    assert make("hedge", wait_action="hover").wait_action == "hover"


def test_the_benchmark_flies_hover_worlds_under_a_set_of_their_own() -> None:
    from uamfleet.cli.benchmark import Args, Job, job_options, run_instance

    task = ("validation", "berlin", split_seeds("validation", 1)[0], None, "endpoint_block")
    args = Args(hedge_wait_action="hover", hover_action=True, replan_beam=16)
    rows = run_instance(Job(task, ("replan",), None, job_options(args), args.hover_action))
    plain = run_instance(Job(task, ("replan",), None, job_options(Args(replan_beam=16))))
    assert [r["set"] for r in rows] == ["berlin validation hover"] and plain[0]["set"] == "berlin validation"
    assert rows[0]["td_m"] == plain[0]["td_m"]
    assert job_options(args)["hedge"]["wait_action"] == "hover"
