"""One fleet policy for every fleet size: the set-shaped observation fields and their normaliser statistics."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import torch

from uamfleet.checks import ConfigError
from conftest import small_config

from uamfleet.config import Request, WorldConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.metrics import episode_metrics
from uamfleet.policies.learned import LearnedOptions, spec_of
from uamfleet.presets import make_config
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.checkpoint import trained_spec
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, observed_inputs
from uamfleet.rl.trainer import GreedyPolicy


def test_a_resized_normaliser_pools_the_rows_of_a_set() -> None:
    """Rows with different means: the pooled statistics are the mean and variance of all rows' values together
    (computed here directly from the data), the same for every row of the new length; other fields are kept."""
    rng = np.random.default_rng(0)
    rows = rng.normal(loc=[[0.0, 1.0], [2.0, -1.0], [4.0, 0.5]], scale=[[1.0, 2.0], [0.5, 1.0], [1.0, 0.1]],
                      size=(2000, 3, 2))  # fmt: skip
    own = rng.normal(size=(2000, 4))
    norm = ObservationNormalizer({"others": (3, 2), "self": (4,)})
    norm.update({"others": rows, "self": own})
    for length in (1, 7):
        out = norm.resized({"others": (length, 2), "self": (4,)})
        pooled = out.fields["others"]
        np.testing.assert_allclose(pooled.mean, np.tile(rows.reshape(-1, 2).mean(0), (length, 1)), atol=1e-6)
        np.testing.assert_allclose(pooled.var, np.tile(rows.reshape(-1, 2).var(0), (length, 1)), rtol=1e-5)
        np.testing.assert_array_equal(out.fields["self"].mean, norm.fields["self"].mean)
    with pytest.raises(ValueError, match="'others'"):
        norm.resized({"others": (3, 5), "self": (4,)})


def _untrained_fleet_policy(taxis: int, variant: str = "de_msfea") -> GreedyPolicy:
    cfg = make_config("berlin_fleet", num_taxis=taxis, sinr_min_db=-5.0)
    venv = VectorEnv(cfg, num_envs=1)
    torch.manual_seed(0)
    head = "stops" if variant != "le" else "headings"
    net = MSHAActorCritic(
        venv.single_observation_space,
        NetConfig(
            variant=variant,
            d_model=16,
            action_head=head,
            stop_prior="nearest",
            **observed_inputs(venv.single_observation_space.spaces, variant, head),
        ),
    ).eval()
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    spec = trained_spec(cfg, dataclasses.asdict(net.cfg))
    return GreedyPolicy(net, None, torch.device("cpu"), shapes, taxis, cfg.num_passengers, cfg, spec=spec)


def test_a_two_taxi_policy_flies_one_and_three_taxis() -> None:
    """The untrained stop head flies its prior (nearest stop, another taxi's claims avoided), which serves
    everyone: fitted at reset, it reads one taxi (no rivals, 6 slots) and three (18 slots) and delivers every
    passenger; the world flown is the instance as made (its own 2 requests per taxi, padded to the rows read)."""
    policy = _untrained_fleet_policy(2)
    for taxis in (1, 3):
        cfg = make_fleet_instance("berlin", 1_000_000, num_taxis=taxis, num_requests=2 * taxis)
        traj = policy.fly(cfg)
        assert policy.fitted()[2] is not None and policy.fitted()[2]["stop_claims"] == (6 * taxis, 2)
        assert policy.obs_shapes is not None and policy.obs_shapes["stop_claims"] == (12, 2)  # as built
        m = episode_metrics(traj, cfg.radio)
        assert m.num_requests == 2 * taxis and m.pr_pct == 100.0
    with pytest.raises(ConfigError, match="the world has 19 passenger rows; this policy reads 18"):
        policy.fly(make_fleet_instance("berlin", 1_000_000, num_taxis=3, num_requests=19))


def test_a_policy_that_reads_the_sets_by_position_keeps_its_size() -> None:
    policy = _untrained_fleet_policy(2, variant="le")
    with pytest.raises(ConfigError, match=r"by position \(1 rows\), but the world has 3 taxis: fly it with 2 taxis"):
        policy.fly(make_fleet_instance("berlin", 1_000_000, num_taxis=3, num_requests=3))
    assert policy.fly(make_fleet_instance("berlin", 1_000_000, num_taxis=2, num_requests=2)).num_steps > 0


def test_the_fleet_design_trains_end_to_end_and_flies_another_size(tmp_path) -> None:
    """The shipped fleet design (claims, hover, nearest prior, MAPPO critic) through the trainer on a 2-taxi
    fleet: two PPO iterations, a checkpoint that loads with the claim-aware hovering head, flown with 3 taxis."""
    from uamfleet.rl.trainer import TrainArgs, load_policy, train

    result = train(TrainArgs.from_flat(dict(
        scenario="berlin_fleet", num_taxis=2, action_head="stops", stop_prior="nearest", centralised_critic=True,
        variant="de_msfea", d_model=16, num_heads=2, total_timesteps=2 * 2 * 2 * 16, num_envs=2, num_steps=16,
        num_minibatches=1, update_epochs=1, eval_every=0, run_dir=tmp_path, run_name="fleet", progress=False,
        tensorboard=False, threads=1, shaping=0.0,
    )))  # fmt: skip
    assert result.global_step == 128 and result.iterations == 2
    policy, _ = load_policy(result.run_dir / "last.pt")
    head = policy.net.stop_head
    assert head is not None and head.claims and head.hovers
    cfg = make_fleet_instance("berlin", 1_000_000, num_taxis=3, num_requests=3)
    traj = policy.fly(cfg)
    assert traj.num_steps > 0 and traj.start_pos_m.shape == (3, 2)


def test_the_spec_names_the_fleet_sizes_its_passenger_axis_fits() -> None:
    """6 passenger rows per taxi (12 on 2 taxis) and at most 1024 rows: fleets of 1 to 170 taxis (6 x 170 = 1020,
    6 x 171 = 1026); a window or explicit slots fly a larger fleet."""
    policy = _untrained_fleet_policy(2)
    assert policy.spec is not None
    fits = r"this policy reads 6 passenger rows per taxi, so fleets of 1 to 170 taxi\(s\) fit .* at most 1024 rows"
    for taxis in (171, 1024):
        world = dataclasses.replace(policy.spec, fleet_rows=None)
        refusal = world.reads(_fleet_world(taxis))
        assert refusal is not None and re.match(rf"^the world has {taxis} taxis and {fits}", refusal)
    assert policy.spec.reads(_fleet_world(170)) is None and policy.spec.rows(_fleet_world(170)) == 1020
    slots = spec_of(policy, LearnedOptions(taxis=171, passenger_slots=1024))
    assert slots.reads(_fleet_world(171)) is None and slots.rows(_fleet_world(171)) == 1024
    window = spec_of(policy, LearnedOptions(passenger_window=12))
    assert window.reads(_fleet_world(171)) is None and window.rows(_fleet_world(171)) == 12


def _fleet_world(taxis: int) -> WorldConfig:
    """A world of ``taxis`` taxis and one request (no env is built: the spec reads its sizes)."""
    return small_config("\n".join(["......."] * 7), starts_m=None, num_taxis=taxis,
                        requests=(Request(0, (250.0, 250.0), (550.0, 450.0)),)).world  # fmt: skip


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("passenger_slots", 0, r"^passenger_slots=0 must be an integer in \[1, 1024\]"),
        ("passenger_slots", 2.5, r"^passenger_slots=2\.5 must be a whole number in \[1, 1024\]"),
        ("passenger_slots", 4096, r"^passenger_slots=4096 is too large: at most 1024 "),
        ("passenger_slots", "24", r"^passenger_slots='24' is a str, not a number"),
        ("passenger_window", True, r"^passenger_window=True is a bool, not a number"),
        ("passenger_window", 10**6, r"^passenger_window=1000000 is too large: at most 1024 "),
        ("passenger_window", float("nan"), r"^passenger_window=nan must be a whole number"),
    ],
)
def test_the_learned_options_check_the_passenger_axis(option, value, message) -> None:
    with pytest.raises(ConfigError, match=message):
        LearnedOptions(taxis=3, **{option: value})
