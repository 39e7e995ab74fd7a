"""One factory: a flight by name (``uamfleet rollout`` / ``render``, a planner in the fleet benchmark) is built by the
registry, with the wider searches one flight affords passed as options, and the benchmarks' defaults stay
the registry's own."""

from __future__ import annotations

import pytest

import uamfleet.baselines
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.checks import ConfigError
from uamfleet.policies import make, make_flown


def test_a_bare_step_planner_flies_the_wider_searches_of_one_flight() -> None:
    replan = make_flown("replan")
    assert isinstance(replan, StepPlannerPolicy) and replan.settings == (SearchSettings(128, rank_slack=0.5),)
    assert make_flown("best_known").settings == (
        SearchSettings(256, rank_slack=1.0), SearchSettings(256, rank_slack=0.0), SearchSettings(1024, rank_slack=0.5)
    )  # fmt: skip
    assert make("replan").settings == (SearchSettings(64, rank_slack=1.0),)  # the benchmarks' default
    assert make_flown("replan:beam=16").settings == (SearchSettings(16, rank_slack=1.0),)  # given: the registry's


def test_the_fleet_benchmark_flies_a_named_planner_as_one_flight() -> None:
    from uamfleet.cli.fleet_benchmark import dispatcher

    assert dispatcher("replan", 1, None, None).settings == (SearchSettings(128, rank_slack=0.5),)
    assert dispatcher("replan:beam=32", 1, None, None).settings == (SearchSettings(32, rank_slack=1.0),)


def test_a_flight_by_name_takes_planners_and_dispatchers_only() -> None:
    random = make_flown("random", seed=5, num_taxis=3)
    assert isinstance(random, RandomPolicy)
    assert random.rng.integers(1 << 30) == RandomPolicy(seed=5).rng.integers(1 << 30)
    assert make_flown("batch_assignment+wait=1+release", num_taxis=2).assign_on_release
    with pytest.raises(ConfigError, match=r"^--policy 'learned' is a learned policy; a flight by name takes"):
        make_flown("learned")
    with pytest.raises(ConfigError, match=r"^--policy replan_futures is a single-taxi planner but the fleet has 2"):
        make_flown("replan_futures", num_taxis=2)
    assert not hasattr(uamfleet.baselines, "make_policy")  # the registry is the one factory


def test_two_policies_of_one_source_share_the_weights_but_not_the_loop_guard() -> None:
    """The loop guard keeps the episode's moves: two policies made from one source (two decodings of one
    checkpoint, a search and its base) each get their own, over the one network loaded per process."""
    from uamfleet.rl.idle_wait import IdleWait
    from uamfleet.rl.loop_guard import LoopGuard

    first, second = make("learned", source="berlin_fleet"), make("learned", source="berlin_fleet")
    assert first is not second and first.net is second.net
    assert isinstance(first.loop_guard, LoopGuard) and first.loop_guard is not second.loop_guard
    assert make("learned", source="berlin_fleet", loop_guard=False).loop_guard is None
    assert isinstance(make("learned", source="berlin_fleet", idle_wait=True).loop_guard, IdleWait)
    claims = make("fleet_claims"), make("fleet_claims", hover_when_idle=True)
    assert claims[0].policy.loop_guard is not claims[1].policy.loop_guard
