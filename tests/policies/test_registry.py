"""The registry builds the baselines' and the learned policies' classes with the settings their options name: the
same objects the benchmarks built from the recorded names (their classes constructed here by hand)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from uamfleet import policies
from uamfleet.baselines.assignment_value import LinearValue, value_for_dispatcher
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy, InsertionPolicy
from uamfleet.baselines.finish import FinishWithSearch
from uamfleet.baselines.greedy_fleet import GreedyFleetPolicy
from uamfleet.baselines.planner_policy import PlannerPolicy
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.policies import PolicyNameError, make, make_named
from uamfleet.policies.planners import FamilyReplan
from uamfleet.rl.guided import AnticipatingGuidedSearch, GuidedSearchPolicy
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.zoo import pretrained

ROOT = Path(__file__).resolve().parents[2]


def same_value(a: LinearValue | None, b: LinearValue | None) -> bool:
    if a is None or b is None:
        return a is b
    return bool(np.array_equal(a.weights, b.weights)) and (a.price_s, a.horizon_s, a.arrival_window_s) == (
        b.price_s, b.horizon_s, b.arrival_window_s)  # fmt: skip


def test_available_lists_every_kind_and_the_benchmarks_policies() -> None:
    kinds = {name: kind for name, (kind, _) in policies.available().items()}
    assert kinds == {
        "cptsp": "planner", "pdpcc": "planner", "raster_replan": "planner", "raster_opt": "planner",
        "straight": "planner", "replan": "planner", "best_known": "planner", "replan_futures": "planner",
        "random": "planner", "greedy": "dispatcher", "insertion": "dispatcher", "batch_assignment": "dispatcher",
        "batch_assignment_value": "dispatcher", "learned": "learned", "fleet_claims": "dispatcher", "argmax": "search",
        "guided": "search", "hedge": "search", "finish": "search", "fleet_search": "search",
    }  # fmt: skip
    assert set(policies.available("dispatcher")) == {"greedy", "insertion", "batch_assignment", V, "fleet_claims"}


V = "batch_assignment_value"


def test_kind_of_a_name_in_the_string_form() -> None:
    assert policies.kind_of("replan:beam=4") == "planner"
    assert policies.kind_of("batch_assignment_value:100+wait=1+release+price=1000+guard=600") == "dispatcher"
    assert policies.kind_of("fleet_search(batch_assignment)") == "search"
    assert policies.kind_of("learned:source=berlin_fleet") == "learned"
    assert policies.kind_of("no_such_policy") is None
    assert policies.kind_of("CPTSP") is None  # a published figure's label names no policy
    with pytest.raises(PolicyNameError, match="beam"):
        policies.kind_of("replan:beam=many")


def test_planners_carry_the_benchmarks_search_settings() -> None:
    assert isinstance(make("straight"), PlannerPolicy) and make("straight").planner == "straight"
    replan = make("replan")
    assert isinstance(replan, StepPlannerPolicy)
    assert replan.planner == "replan" and replan.settings == (SearchSettings(64, rank_slack=1.0),)
    best = make("best_known", beams=(256, 128, 64))
    assert best.settings == (SearchSettings(256, rank_slack=1.0), SearchSettings(128, rank_slack=0.0),
                             SearchSettings(64, rank_slack=1.0))  # fmt: skip
    assert isinstance(make("replan_futures"), FamilyReplan)
    assert make("random", seed=3).rng.integers(1 << 30) == RandomPolicy(seed=3).rng.integers(1 << 30)


def test_dispatchers_are_the_ones_the_recorded_names_built() -> None:
    assert isinstance(make("greedy"), GreedyFleetPolicy)
    assert isinstance(make("insertion", wait=2), InsertionPolicy) and make("insertion", wait=2).wait_weight == 2.0
    for recorded, (wait, release, price, guard, value) in {
        "batch_assignment+wait=1+release": (1.0, True, None, None, None),
        f"{V}:100+wait=1.5+release+price=1000+guard=600": (1.5, True, 1000.0, 600.0, f"{V}:100"),
        f"{V}:30": (0.0, False, None, None, f"{V}:30"),
    }.items():
        new = make_named(recorded)
        old = BatchAssignmentPolicy(
            value=None if value is None else value_for_dispatcher(value, None, None), wait_weight=wait,
            assign_on_release=release, unassigned_price_s=price, unassigned_guard_s=guard,
        )  # fmt: skip
        assert isinstance(new, BatchAssignmentPolicy)
        for attr in ("wait_weight", "assign_on_release", "unassigned_price_s", "unassigned_guard_s", "period"):
            assert getattr(new, attr) == getattr(old, attr), (recorded, attr)
        assert same_value(new.value, old.value)
    assert make(V, value_price_s=100.0).value.price_s == 100.0
    assert make("batch_assignment").value is None


def test_a_refit_value_stem_reads_its_file_and_a_missing_one_is_named() -> None:
    refit = make_named(f"{V}:100+wait=1+release@refit_both")
    assert same_value(refit.value, value_for_dispatcher(
        f"{V}:100", ROOT / "docs/results/assignment_value_refit/refit_both.json", None,
    ))  # fmt: skip
    assert not same_value(refit.value, make_named(f"{V}:100+wait=1+release").value)
    with pytest.raises(FileNotFoundError, match="value='no_such_fit' is neither a file nor a stem"):
        make(V, value="no_such_fit")


def test_learned_policies_and_their_fleet_options() -> None:
    shipped = make("learned")
    assert isinstance(shipped, GreedyPolicy) and shipped.num_taxis == 1
    assert shipped.thresholds_db == pretrained("berlin").thresholds_db
    fleet = make("learned", source="berlin_fleet", taxis=4, passenger_window=24)
    assert fleet.spec.passenger_window == 24 and fleet.spec.time_scale_steps is None  # any fleet, any shift
    slots = make("learned", source="berlin_fleet_v1", taxis=2, passenger_slots=10)
    assert slots.spec.slots_per_taxi == 5 and slots.spec.passenger_window is None  # 10 rows for 2 taxis
    unguarded = make("learned", loop_guard=False)
    assert unguarded.loop_guard is None and make("learned").loop_guard is not None  # the cached one is untouched
    with pytest.raises(PolicyNameError, match="passenger_slots='world' is read against a world"):
        make_named("learned:berlin_fleet4")
    with pytest.raises(FileNotFoundError, match="neither a shipped policy"):
        make("learned", source="runs/none/best.pt")


def test_search_wrappers_over_a_learned_base() -> None:
    base = make("learned")
    assert make("argmax", base=base) is base
    guided = make("guided", base=base, top_k=4, horizon=40)
    assert isinstance(guided, GuidedSearchPolicy) and guided.policy is base
    assert (guided.top_k, guided.samples, guided.horizon) == (4, 24, 40)
    hedge = make_named("learned_hedge")
    assert isinstance(hedge, AnticipatingGuidedSearch) and hedge.policy.traced and hedge.policy is not base
    assert (hedge.first_headings, hedge.futures, hedge.commit, hedge.tail, hedge.samples) == (4, 8, 4, 10, 8)
    assert make("hedge", tail=-1).tail is None
    finish = make("finish", base="replan", beam=4)
    assert isinstance(finish, FinishWithSearch) and isinstance(finish.policy, StepPlannerPolicy)
    assert finish.beam == 4
    with pytest.raises(PolicyNameError, match="guided searches over a learned policy's logits"):
        make("guided", base="replan")
