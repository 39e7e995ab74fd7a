"""One fleet policy for every fleet size: the set-shaped observation fields and their normaliser statistics."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from uamfleet.checks import ConfigError
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.metrics import episode_metrics
from uamfleet.presets import make_config
from uamfleet.rl.buffer import ObservationNormalizer
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
    return GreedyPolicy(net, None, torch.device("cpu"), shapes, taxis, cfg.num_passengers, cfg)


def test_a_two_taxi_policy_flies_one_and_three_taxis() -> None:
    """The untrained stop head flies its prior (nearest stop, another taxi's claims avoided), which serves
    everyone: resized, it reads one taxi (no rivals, 6 slots) and three (18 slots) and delivers every passenger."""
    policy = _untrained_fleet_policy(2)
    assert policy.for_fleet(2) is policy
    for taxis in (1, 3):
        resized = policy.for_fleet(taxis)
        assert resized.num_taxis == taxis and resized.passenger_slots == 6 * taxis
        assert resized.obs_shapes is not None and resized.obs_shapes["stop_claims"] == (6 * taxis, 2)
        cfg = make_fleet_instance("berlin", 1_000_000, num_taxis=taxis, num_requests=2 * taxis)
        m = episode_metrics(resized.fly(cfg), cfg.radio)
        assert m.num_requests == 2 * taxis and m.pr_pct == 100.0
    with pytest.raises(ValueError, match="3 taxi"):
        policy.layout(make_fleet_instance("berlin", 1_000_000, num_taxis=3, num_requests=2))


def test_a_policy_that_reads_the_sets_by_position_keeps_its_size() -> None:
    with pytest.raises(ValueError, match="designed variant"):
        _untrained_fleet_policy(2, variant="le").for_fleet(3)


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
    traj = policy.for_fleet(3).fly(cfg)
    assert traj.num_steps > 0 and traj.start_pos_m.shape == (3, 2)


def test_for_fleet_names_the_fleet_sizes_its_passenger_axis_fits() -> None:
    """6 passenger rows per taxi (12 on 2 taxis) and at most 1024 rows: fleets of 1 to 170 taxis (6 x 170 = 1020,
    6 x 171 = 1026); a window or explicit slots fly a larger fleet."""
    policy = _untrained_fleet_policy(2)
    fits = r"it reads 6 passenger rows per taxi, so fleets of 1 to 170 taxi\(s\) fit .* at most 1024 rows"
    for taxis in (171, 1024):
        with pytest.raises(ConfigError, match=rf"^num_taxis={taxis} is out of range for this policy: {fits}"):
            policy.for_fleet(taxis)
    assert policy.for_fleet(170).passenger_slots == 1020
    assert policy.for_fleet(171, passenger_slots=1024).passenger_slots == 1024
    assert policy.for_fleet(171, passenger_window=12).passenger_slots == 12


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
def test_for_fleet_checks_its_passenger_axis(option, value, message) -> None:
    with pytest.raises(ConfigError, match=message):
        _untrained_fleet_policy(2).for_fleet(3, **{option: value})
