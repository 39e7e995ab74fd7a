"""The one ``Policy`` protocol (uamfleet/env/protocol.py): every policy the registry builds satisfies it, rollout
resets a policy with the simulator and acts through ``act``, and the policies that read a demand model take the
instance family from the simulator's world (refusing, in one line, a world no family draws)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import uamfleet
from uamfleet import policies
from uamfleet.baselines.anticipation import NoDemandModelError, world_family
from uamfleet.env.protocol import Policy
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FAMILIES, make_fleet_instance, make_instance
from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, StopsSpec
from uamfleet.rollout import run_episode
from uamfleet.sim.core import Simulator


def test_every_registered_policy_satisfies_the_protocol() -> None:
    for name, (kind, _) in policies.available().items():
        policy = policies.make(name)
        assert isinstance(policy, Policy), f"{name} ({kind}) lacks spec, reset(sim) or act(obs)"


def test_planners_read_the_state_and_learned_policies_say_what_they_read() -> None:
    assert policies.make("replan").spec is None and policies.make("greedy").spec is None
    learned = policies.make("learned")  # berlin.pt: 6 rows per taxi, stops, the two-move look-ahead
    assert learned.spec == ObserverSpec(slots_per_taxi=6.0, time_scale_steps=600, stops=StopsSpec(),
                                        lookahead=LookaheadSpec(depth=2))  # fmt: skip
    layout = learned.spec.layout(uamfleet.make_config("berlin_instances").world)
    assert {k: layout[k].shape for k in learned.obs_shapes} == learned.obs_shapes and "action_mask" in layout
    assert policies.make("guided", base=learned).spec is learned.spec
    assert policies.make("finish", base=learned).spec is learned.spec
    assert policies.make("finish", base="replan").spec is None


class Recording:
    """Records what rollout hands it: the simulator at reset, each ``act``; ``__call__`` must not be used."""

    spec = None

    def __init__(self) -> None:
        self.sims: list[Any] = []
        self.acts = 0

    def reset(self, sim: Any) -> None:
        self.sims.append(sim)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        self.acts += 1
        return np.zeros(obs["action_mask"].shape[:2], np.int64)

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        raise AssertionError("rollout acts through act(obs)")


def test_rollout_resets_with_the_simulator_then_acts() -> None:
    env = VectorEnv(uamfleet.make_config("berlin_p4", time_limit_steps=7), num_envs=1, autoreset=False)
    policy = Recording()
    assert isinstance(policy, Policy)
    traj = run_episode(env, policy, seed=0)
    assert len(policy.sims) == 1 and policy.sims[0] is env.sim and isinstance(env.sim, Simulator)
    assert policy.acts == traj.num_steps == 7


def test_the_family_is_read_from_the_world() -> None:
    assert world_family(make_instance("berlin", 3), "hedge") == "berlin"
    assert world_family(make_instance("detroit3gpp", 1), "hedge") == "detroit3gpp"
    assert world_family(make_fleet_instance("berlin", 2, num_taxis=2, num_requests=4), "finish") == "berlin"
    for scenario, family in [("berlin_instances", "berlin"), ("berlin_fleet", "berlin"),
                             ("detroit3gpp_random", "detroit3gpp")]:  # fmt: skip
        assert world_family(uamfleet.make_config(scenario), "finish") == family
    for fixed in ("berlin_p4", "detroit_p5", "detroit3gpp_p5"):
        with pytest.raises(NoDemandModelError, match=rf"^replan_futures reads .*'{fixed}'.* not a fixed scenario\.$"):
            world_family(uamfleet.make_config(fixed), "replan_futures")
    assert issubclass(NoDemandModelError, ValueError)


@pytest.mark.parametrize("name", ["replan_futures", "hedge", "finish"])
def test_a_demand_model_policy_refuses_a_fixed_scenario_at_reset(name: str) -> None:
    env = VectorEnv(uamfleet.make_config("berlin_p4"), num_envs=1, autoreset=False)
    env.reset(seed=0)
    with pytest.raises(NoDemandModelError, match=rf"^{name} reads an instance family's demand model.*'berlin_p4'"):
        policies.make(name).reset(env.sim)


def test_finish_takes_the_window_of_the_worlds_family() -> None:
    cfg = make_instance("detroit3gpp", 1)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    finish = policies.make("finish", base="replan", beam=2)
    finish.reset(env.sim)
    fam = FAMILIES["detroit3gpp"]
    assert (finish.window_steps, finish.max_requests) == (int(fam.release_window_s // cfg.slot_s), fam.max_passengers)
    assert finish.window_steps != int(FAMILIES["berlin"].release_window_s // 3.0)  # not berlin's 3 s slots


def test_hedge_takes_the_demand_model_of_the_worlds_family() -> None:
    hedge = policies.make("hedge", futures=1, first_headings=1, samples=0, top_k=1, tail=0)
    cfg = make_instance("berlin", 3)  # 4 passenger rows: the hedge pads its own futures to the 6 it samples
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=hedge.spec)  # observed as its policy reads
    env.reset(seed=0)
    hedge.reset(env.sim)
    fam = FAMILIES["berlin"]
    prior = hedge.prior
    assert (prior.min_requests, prior.max_requests, prior.min_trip_m) == (
        fam.min_passengers, fam.max_passengers, fam.min_trip_m)  # fmt: skip
    assert prior.window_steps == fam.window_steps(cfg.slot_s)
