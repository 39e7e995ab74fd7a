"""The generalist's parts: the stop head (hand-computed mixture), the padded passenger axis (a masked slot
changes nothing), training on a threshold mixture with validation instances, and load_policy on another
threshold and passenger count."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_instance
from uamfleet.metrics import episode_metrics
from uamfleet.presets import make_config
from uamfleet.rl.heads import CLAIM_INIT, HOVER_LEAD, StopHead
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, obs_to_torch, observed_inputs
from uamfleet.rl.trainer import TrainArgs, load_policy, train
from uamfleet.types import NUM_HEADINGS


def test_stop_head_is_the_hand_computed_mixture() -> None:
    """Zero weights: every actionable stop and the free move get equal weight 1 / (n + 1); a stop puts its weight
    on its heading, the free move spreads its own uniformly over the allowed headings."""
    head = StopHead(features=3, d_model=2, hidden=4, free_bias=0.0, free_move=True)
    with torch.no_grad():
        for p in head.parameters():
            p.zero_()
    heading_mask = torch.zeros(1, 3, NUM_HEADINGS)
    heading_mask[0, 0, 5] = 1  # stop 0 -> heading 5
    heading_mask[0, 1, 5] = 1  # stop 1 -> heading 5 as well
    # row 2 is not actionable
    allowed = torch.zeros(1, NUM_HEADINGS, dtype=torch.bool)
    allowed[0, [0, 5, 9, 12]] = True
    free_logits = torch.zeros(1, NUM_HEADINGS).masked_fill(~allowed, torch.finfo(torch.float32).min)
    with torch.no_grad():
        logp = head(torch.zeros(1, 3), torch.zeros(1, 3, 2), heading_mask, free_logits)
    probs = logp.exp()[0]
    expected = torch.zeros(NUM_HEADINGS)
    expected[5] += 2 / 3  # two stops of three components
    expected[[0, 5, 9, 12]] += (1 / 3) / 4  # the free component over 4 allowed headings
    torch.testing.assert_close(probs, expected, atol=1e-6, rtol=0)
    assert math.isclose(float(probs.sum()), 1.0, abs_tol=1e-6)


def test_claims_lower_another_taxis_stops_and_open_the_free_move_when_all_are_claimed() -> None:
    """Zero learned weights and no tour prior: a stop claimed by another taxi starts CLAIM_INIT logits lower; the
    free move (closed while an unclaimed stop is left) opens when every stop is another taxi's."""
    head = StopHead(features=3, d_model=2, hidden=4, free_bias=0.0, claims=True)
    with torch.no_grad():
        for p in head.parameters():
            p.zero_()
        head.log_claim_weight.fill_(math.log(CLAIM_INIT))
    heading_mask = torch.zeros(2, 2, NUM_HEADINGS)
    heading_mask[:, 0, 3] = 1  # stop 0 -> heading 3
    heading_mask[:, 1, 7] = 1  # stop 1 -> heading 7
    free_logits = torch.zeros(2, NUM_HEADINGS)  # every heading allowed
    claimed = torch.tensor([[True, False], [True, True]])
    with torch.no_grad():
        probs = head(torch.zeros(2, 3), torch.zeros(2, 2, 2), heading_mask, free_logits, None, claimed).exp()
    low = math.exp(-CLAIM_INIT)
    one = torch.zeros(NUM_HEADINGS)  # sample 0: stop 1 is open, so the free move is closed
    one[3], one[7] = low / (low + 1), 1 / (low + 1)
    two = torch.full((NUM_HEADINGS,), 1 / 16) * (1 / (2 * low + 1))  # sample 1: free move weight 1 of 2e^-8 + 1
    two[3] += low / (2 * low + 1)
    two[7] += low / (2 * low + 1)
    torch.testing.assert_close(probs, torch.stack([one, two]), atol=1e-6, rtol=0)
    with pytest.raises(ValueError, match="claimed_by_other"):
        head(torch.zeros(2, 3), torch.zeros(2, 2, 2), heading_mask, free_logits)


def test_an_idle_taxi_hovers_first_and_a_taxi_with_an_open_stop_never_does() -> None:
    """With every stop claimed by others, the free move (score 0) and the hover component (HOVER_LEAD) open:
    hovering starts e^HOVER_LEAD times as likely as the free move; with an open stop both stay closed."""
    head = StopHead(features=3, d_model=2, hidden=4, free_bias=0.0, claims=True, hover=True)
    with torch.no_grad():
        for p in head.parameters():
            p.zero_()
        head.log_claim_weight.fill_(math.log(CLAIM_INIT))
        head.hover.bias.fill_(HOVER_LEAD)
    heading_mask = torch.zeros(2, 2, NUM_HEADINGS)
    heading_mask[:, 0, 3] = 1
    heading_mask[:, 1, 7] = 1
    hover_mask = torch.zeros(2, NUM_HEADINGS)
    hover_mask[:, 12] = 1  # back where the taxi came from
    claimed = torch.tensor([[True, True], [True, False]])
    with torch.no_grad():
        probs = head(
            torch.zeros(2, 3), torch.zeros(2, 2, 2), heading_mask, torch.zeros(2, NUM_HEADINGS), None, claimed,
            hover_mask,
        ).exp()  # fmt: skip
    low, lead = math.exp(-CLAIM_INIT), math.exp(HOVER_LEAD)
    z = 2 * low + 1 + lead
    idle = torch.full((NUM_HEADINGS,), 1 / 16 / z)
    idle[3] += low / z
    idle[7] += low / z
    idle[12] += lead / z
    busy = torch.zeros(NUM_HEADINGS)
    busy[3], busy[7] = low / (low + 1), 1 / (low + 1)
    torch.testing.assert_close(probs, torch.stack([idle, busy]), atol=1e-6, rtol=0)


def _policy_net(**cfg_kwargs: object) -> tuple[MSHAActorCritic, dict[str, np.ndarray]]:
    venv = VectorEnv(make_config("berlin_instances", sinr_min_db=-5.0), num_envs=4)
    obs, _ = venv.reset(seed=3)
    torch.manual_seed(0)
    inputs = observed_inputs(
        venv.single_observation_space.spaces, "de_msfea", str(cfg_kwargs.get("action_head", "headings"))
    )
    net = MSHAActorCritic(
        venv.single_observation_space,
        NetConfig(variant="de_msfea", d_model=32, **inputs, **cfg_kwargs),  # type: ignore[arg-type]
    )
    return net, {k: v.reshape(4, *v.shape[2:]) for k, v in obs.items()}


@pytest.mark.parametrize("action_head", ["headings", "stops"])
def test_a_masked_passenger_slot_changes_nothing(action_head: str) -> None:
    net, obs = _policy_net(action_head=action_head)
    padding = ~obs["passenger_mask"].astype(bool)  # [B, P] slots not released (or not requests at all)
    assert padding.any()
    garbage = {k: v.copy() for k, v in obs.items()}
    rng = np.random.default_rng(1)
    garbage["passengers"][padding] = rng.normal(size=garbage["passengers"][padding].shape) * 5
    garbage["stop_paths"][padding] = rng.uniform(0, 3, size=garbage["stop_paths"][padding].shape)
    with torch.no_grad():
        logits, value = net(obs_to_torch(obs, "cpu"))
        logits2, value2 = net(obs_to_torch(garbage, "cpu"))
    torch.testing.assert_close(logits, logits2)
    torch.testing.assert_close(value, value2)


def test_the_stop_head_flies_only_marked_headings_while_a_stop_is_actionable() -> None:
    net, obs = _policy_net(action_head="stops")
    with torch.no_grad():
        probs = net.masked_logits(obs_to_torch(obs, "cpu")).softmax(-1).numpy()  # [B, 16]
    marked = obs["stop_heading_mask"].max(1).astype(bool)  # [B, 16] headings of some actionable stop
    assert marked.any(-1).all()
    np.testing.assert_allclose((probs * marked).sum(-1), 1.0, atol=1e-5)
    # with the free move on, it starts with a small weight beside the stops
    net, _ = _policy_net(action_head="stops", stop_free_move=True)
    with torch.no_grad():
        probs = net.masked_logits(obs_to_torch(obs, "cpu")).softmax(-1).numpy()
    assert 0.7 < (probs * marked).sum(-1).min() < 1.0 - 1e-4
    assert np.all(probs[~obs["action_mask"].astype(bool)] == 0)


def test_the_stop_head_needs_stop_features() -> None:
    venv = VectorEnv(make_config("berlin_random", num_taxis=1), num_envs=1)
    with pytest.raises(ValueError, match="stop features"):
        MSHAActorCritic(venv.single_observation_space, NetConfig(variant="de", action_head="stops"))
    with pytest.raises(ValueError, match="linear encoder"):
        NetConfig(variant="le", action_head="stops")


@pytest.fixture(scope="module")
def generalist_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two iterations on a -7 / -3 dB mixture, evaluated on 3 validation instances (a tiny, untrained policy)."""
    args = TrainArgs.from_flat(dict(
        scenario="berlin_instances", thresholds=(-7.0, -3.0), action_head="stops", d_model=16, num_heads=2,
        eval_instances=3, time_limit_steps=120, num_envs=4, num_steps=16, num_minibatches=2, update_epochs=1,
        total_timesteps=2 * 4 * 16, eval_every=1, run_dir=tmp_path_factory.mktemp("runs"), run_name="g",
        progress=False, tensorboard=False, threads=1, device="cpu", fill_tables=False,
    ))  # fmt: skip
    result = train(args)
    assert result.iterations == 2
    assert result.best_eval["instances"] == 3.0
    assert 0.0 <= result.best_eval["pr_pct"] <= 100.0
    return result.run_dir / "best.pt"


def test_load_policy_flies_another_threshold_and_fewer_passengers(generalist_run: Path) -> None:
    # another threshold than either trained one, and Berlin P4's 4 requests on the 6 slots
    p4 = make_config("berlin_p4", sinr_min_db=-5.0)
    policy, args = load_policy(generalist_run, env_config=p4.replace(max_passengers=6, stop_features=True))
    assert args.env.thresholds == (-7.0, -3.0)
    traj = policy.fly(p4)  # the world as given, its 4 passenger rows read as the 6 the policy reads (padded)
    shapes = policy.fitted()[2]
    assert shapes is not None and shapes["passengers"][0] == 6 and "stop_paths" in shapes
    assert traj.sinr_min_db == -5.0  # the threshold of the config given, never the checkpoint's
    np.testing.assert_array_equal(traj.start_pos_m, np.array(p4.starts_m))
    m = episode_metrics(traj, p4.radio, threshold_db=-5.0)
    assert m.num_requests == 4
    # a held-out instance with 2 requests (another start and threshold) flies too
    seeds = range(2_000_000, 2_000_050)
    small = next(cfg for cfg in (make_instance("berlin", s) for s in seeds) if cfg.num_requests_max == 2)
    assert policy.fly(small).sinr_min_db == small.sinr_min_db


def test_load_policy_names_what_differs(generalist_run: Path) -> None:
    with pytest.raises(ValueError, match="max_passengers=6"):
        load_policy(generalist_run, env_config=make_config("berlin_instances", max_passengers=8))
    policy, _ = load_policy(generalist_run)
    too_many = make_config("berlin_random", num_taxis=1, max_passengers=None)  # 12 requests
    with pytest.raises(ValueError, match="the world has 12 passenger rows; this policy reads 6"):
        policy.fly(too_many)
