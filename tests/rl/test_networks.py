"""The MSHA actor-critic: shapes, masking, the hybrid attention's receptive fields, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from gymnasium import spaces

import uamfleet
from uamfleet.observe.observer import ObservationShapeError
from uamfleet.rl.networks import (
    VARIANTS,
    GridReadout,
    HybridAttention,
    MSHAActorCritic,
    MultiSourceFusion,
    NetConfig,
    PointerPool,
    global_attention,
    local_attention,
    mask_logits,
    masked_mean,
    multi_source_features,
    obs_to_torch,
    window_order,
)

STATE_DIM = 41  # berlin_p4, one taxi: 4 + 4 * 9 + 1


def obs_space(k: int = 4, P: int = 4, O: int = 1, H: int = 3) -> spaces.Dict:  # noqa: E741
    """The per-taxi space of uamfleet.observe.observer for patch size k, P passenger slots, O other-taxi rows."""
    f32 = np.float32
    return spaces.Dict(
        {
            "self": spaces.Box(-1.0, 1.0, (4,), f32),
            "history": spaces.Box(-2.0, 2.0, (H, 3), f32),
            "passengers": spaces.Box(-2.0, 2.0, (P, 12), f32),
            "passenger_mask": spaces.Box(0, 1, (P,), np.int8),
            "sinr_patch": spaces.Box(-30.0, 30.0, (k, k), f32),
            "visit_patch": spaces.Box(0.0, 1.0, (k, k), f32),
            "others": spaces.Box(-2.0, 2.0, (O, 3), f32),
            "others_mask": spaces.Box(0, 1, (O,), np.int8),
            "action_mask": spaces.Box(0, 1, (16,), np.int8),
        }
    )


def random_obs(space: spaces.Dict, batch: int, seed: int = 0) -> dict[str, torch.Tensor]:
    """A batch of plausible observations: about half the passengers released (unreleased rows all zero)."""
    rng = np.random.default_rng(seed)
    obs: dict[str, np.ndarray] = {}
    for key, sub in space.spaces.items():
        shape = (batch, *sub.shape)
        if key.endswith("mask"):
            obs[key] = (rng.random(shape) < (0.9 if key == "action_mask" else 0.6)).astype(np.int8)
        elif key == "sinr_patch":
            obs[key] = rng.uniform(-30.0, 30.0, shape).astype(np.float32)
        else:
            obs[key] = rng.uniform(-1.0, 1.0, shape).astype(np.float32)
    obs["passengers"] *= obs["passenger_mask"][..., None]
    obs["others"] *= obs["others_mask"][..., None]
    obs["action_mask"][:, 0] = 1  # every row keeps an allowed action, as the env guarantees
    return obs_to_torch(obs, "cpu")


def make_net(variant: str, space: spaces.Dict, **kwargs) -> MSHAActorCritic:
    torch.manual_seed(0)
    return MSHAActorCritic(space, NetConfig(variant=variant, **kwargs)).eval()


# ------------------------------------------------------------------------------------------------ shapes


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize(("k", "P"), [(10, 4), (4, 7), (2, 1)])  # k = 2: one 2 x 2 window
@pytest.mark.parametrize("state_dim", [None, STATE_DIM])
def test_output_shapes(variant, k, P, state_dim):
    space = obs_space(k=k, P=P, O=2)
    net = make_net(variant, space, critic_state_dim=state_dim)
    obs = random_obs(space, batch=5)
    state = None if state_dim is None else torch.randn(5, state_dim)
    logits, value = net(obs, state=state)
    assert logits.shape == (5, 16) and value.shape == (5,)
    assert torch.isfinite(value).all()
    action, log_prob, entropy, value2 = net.get_action_and_value(obs, state=state)
    assert action.shape == log_prob.shape == entropy.shape == value2.shape == (5,)
    assert action.dtype == torch.long
    assert torch.isfinite(log_prob).all() and torch.isfinite(entropy).all()
    torch.testing.assert_close(value2, value)
    assert net.masked_logits(obs).shape == (5, 16)


def test_real_env_observation_goes_through():
    venv = uamfleet.vector_env("berlin_p4", num_envs=2)
    obs, _ = venv.reset(seed=0)
    flat = {key: value.reshape(-1, *value.shape[2:]) for key, value in obs.items()}  # [E * A, ...]
    tensors = obs_to_torch(flat, "cpu")
    assert all(t.dtype == torch.float32 for t in tensors.values())
    net = make_net("full", venv.single_observation_space, critic_state_dim=int(venv.state_space.shape[0]))
    state = torch.as_tensor(venv.global_state(), dtype=torch.float32)
    logits, value = net(tensors, state=state)
    assert logits.shape == (2, 16) and value.shape == (2,)


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_parameter_gets_a_gradient(variant):
    space = obs_space(k=4, P=4, O=2)
    net = make_net(variant, space)
    _, log_prob, entropy, value = net.get_action_and_value(random_obs(space, batch=6))
    (log_prob.sum() + entropy.sum() + value.sum()).backward()
    unused = [name for name, p in net.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0]
    assert not unused, f"parameters without gradient: {unused}"


def test_initial_policy_is_near_uniform_and_heads_use_cleanrl_init():
    space = obs_space(k=4)
    net = make_net("full", space)
    out_layer = net.actor[-1]
    assert isinstance(out_layer, torch.nn.Linear)
    # orthogonal with gain 0.01: the rows are orthogonal with norm 0.01
    gram = out_layer.weight @ out_layer.weight.T
    torch.testing.assert_close(gram, 1e-4 * torch.eye(16), atol=1e-7, rtol=0)
    obs = random_obs(space, batch=4)
    obs["action_mask"][:] = 1
    logits, _ = net(obs)
    assert logits.abs().max() < 0.1


def test_same_seed_same_network_and_actions():
    space = obs_space(k=4)
    obs = random_obs(space, batch=8)
    results = []
    for _ in range(2):
        net = make_net("full", space)
        torch.manual_seed(3)
        results.append(net.get_action_and_value(obs))
    for a, b in zip(*results, strict=True):
        assert torch.equal(a, b)


# ------------------------------------------------------------------------------------ passenger masking


@pytest.mark.parametrize("variant", VARIANTS)
def test_unreleased_passenger_content_is_invisible(variant):
    space = obs_space(k=4, P=4, O=2)
    net = make_net(variant, space)
    obs = random_obs(space, batch=3)
    obs["passenger_mask"][:] = torch.tensor([1.0, 0.0, 1.0, 0.0])
    obs["passengers"][:, [1, 3]] = 0.0
    obs["others_mask"][:] = torch.tensor([1.0, 0.0])
    obs["others"][:, 1] = 0.0
    garbage = {key: value.clone() for key, value in obs.items()}
    garbage["passengers"][:, 1] = 1e4 * torch.randn(3, 12)
    garbage["passengers"][:, 3] = float("nan")
    garbage["others"][:, 1] = 1e4 * torch.randn(3, 3)
    with torch.no_grad():
        logits, value = net(obs)
        logits_g, value_g = net(garbage)
    torch.testing.assert_close(logits_g, logits, atol=1e-6, rtol=0)
    torch.testing.assert_close(value_g, value, atol=1e-6, rtol=0)


@pytest.mark.parametrize("variant", VARIANTS)
def test_no_released_passenger_gives_finite_outputs_blind_to_the_rows(variant):
    space = obs_space(k=4, P=3, O=1)
    net = make_net(variant, space)
    obs = random_obs(space, batch=2)
    obs["passenger_mask"][:] = 0.0
    obs["passengers"][:] = 0.0
    obs["others_mask"][:] = 0.0  # a single taxi: the one "others" row is a placeholder
    obs["others"][:] = 0.0
    garbage = {key: value.clone() for key, value in obs.items()}
    garbage["passengers"][:] = 1e3 * torch.randn(2, 3, 12)
    garbage["others"][:] = 1e3
    with torch.no_grad():
        logits, value = net(obs)
        logits_g, value_g = net(garbage)
    assert torch.isfinite(logits).all() and torch.isfinite(value).all()
    torch.testing.assert_close(logits_g, logits, atol=1e-6, rtol=0)
    torch.testing.assert_close(value_g, value, atol=1e-6, rtol=0)


@pytest.mark.parametrize("variant", VARIANTS)
def test_a_late_released_passenger_changes_the_outputs(variant):
    # Only the last slot is released: the original code's normalised mask hid such late passengers forever.
    space = obs_space(k=4, P=4, O=1)
    net = make_net(variant, space)
    obs = random_obs(space, batch=3)
    obs["passenger_mask"][:] = torch.tensor([0.0, 0.0, 0.0, 1.0])
    obs["passengers"][:, :3] = 0.0
    moved = {key: value.clone() for key, value in obs.items()}
    moved["passengers"][:, 3] = obs["passengers"][:, 3] + 0.5
    with torch.no_grad():
        logits, value = net(obs)
        logits_m, value_m = net(moved)
    assert (logits_m - logits).abs().max() > 1e-5
    assert (value_m - value).abs().max() > 1e-5


@pytest.mark.parametrize("dtype", [torch.bool, torch.int8])
def test_masks_may_be_float_bool_or_int8(dtype):
    space = obs_space(k=4)
    net = make_net("full", space)
    obs = random_obs(space, batch=4)
    cast = dict(obs, **{key: obs[key].to(dtype) for key in ("passenger_mask", "others_mask", "action_mask")})
    with torch.no_grad():
        for a, b in zip(net(obs), net(cast), strict=True):
            torch.testing.assert_close(a, b, atol=0, rtol=0)


def test_given_actions_are_scored_not_resampled():
    space = obs_space(k=4)
    net = make_net("de_msfea", space)
    obs = random_obs(space, batch=6)
    with torch.no_grad():
        action, log_prob, _, _ = net.get_action_and_value(obs)
        logits, _ = net(obs)
        for given in (action, action.float()):  # a buffer may hand actions back as floats
            again = net.get_action_and_value(obs, given)
            assert torch.equal(again[0], action) and again[0].dtype == torch.long
            torch.testing.assert_close(again[1], log_prob)
            torch.testing.assert_close(again[1], torch.log_softmax(logits, -1).gather(1, action[:, None])[:, 0])


# ------------------------------------------------------------------------------------------- fusion parts


def test_masked_mean_by_hand():
    x = torch.tensor([[[1.0, 2.0], [3.0, 4.0], [float("nan"), 1e9]], [[5.0, 6.0], [7.0, 8.0], [9.0, 10.0]]])
    mask = torch.tensor([[True, True, False], [False, False, False]])
    torch.testing.assert_close(masked_mean(x, mask), torch.tensor([[2.0, 3.0], [0.0, 0.0]]))


def test_multi_source_features_is_the_papers_broadcast_concat_mean():
    B, N, D, G, C = 2, 4, 3, 9, 5
    tokens, maps = torch.randn(B, N, D), torch.randn(B, G, C)
    mask = torch.tensor([[True, False, True, True], [True, False, False, False]])
    # literally: each token broadcast over the grid, concatenated with the maps, averaged over valid tokens
    per_token = torch.cat([tokens[:, :, None].expand(B, N, G, D), maps[:, None].expand(B, N, G, C)], dim=-1)
    expected = torch.stack([per_token[b, mask[b]].mean(0) for b in range(B)])  # [B, G, D + C]
    torch.testing.assert_close(multi_source_features(tokens, mask, maps), expected)

    fusion = MultiSourceFusion(D, C, 6)
    torch.testing.assert_close(fusion(tokens, mask, maps), torch.relu(fusion.proj(expected)))


def test_pointer_pool_by_hand_and_blind_to_masked_rows():
    torch.manual_seed(0)
    pool = PointerPool(3)
    taxi, tokens = torch.randn(2, 3), torch.randn(2, 4, 3)
    released = torch.tensor([[True, False, True, True], [False, False, False, False]])
    q = pool.query(taxi)  # [2, 3]
    scores = (tokens[0, released[0]] @ q[0]) / math.sqrt(3)
    expected = torch.softmax(scores, 0) @ tokens[0, released[0]]
    out = pool(taxi, tokens, released)
    torch.testing.assert_close(out[0], expected)
    torch.testing.assert_close(out[1], torch.zeros(3))  # nobody released: zeros, not NaN
    tokens[0, 1] = float("nan")  # garbage in a masked row must not leak
    torch.testing.assert_close(pool(taxi, tokens, released)[0], expected)


def test_flatten_readout_knows_where_a_feature_is_and_mean_does_not():
    torch.manual_seed(0)
    grid = torch.zeros(1, 9, 2)
    grid[0, 0, 0] = 1.0  # a feature in the top-left cell ...
    moved = torch.zeros(1, 9, 2)
    moved[0, 8, 0] = 1.0  # ... or the same feature in the bottom-right cell
    flat, mean = GridReadout(9, 2, 4, "flatten"), GridReadout(9, 2, 4, "mean")
    assert not torch.allclose(flat(grid), flat(moved))
    torch.testing.assert_close(mean(grid), mean(moved))
    assert flat(grid).shape == (1, 4) and mean(grid).shape == (1, 2)


def test_window_order_by_hand():
    # 4 x 4 grid, 2 x 2 windows: the top-left window is cells 0, 1, 4, 5, the top-right 2, 3, 6, 7, ...
    assert window_order(4, 2).tolist() == [0, 1, 4, 5, 2, 3, 6, 7, 8, 9, 12, 13, 10, 11, 14, 15]
    assert window_order(4, 4).tolist() == list(range(16))


def _attention_by_hand(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    scores = q @ k.T / math.sqrt(q.shape[-1])  # head width, not sqrt(32)
    return torch.softmax(scores, dim=-1) @ v


def test_local_and_global_attention_match_hand_computation():
    torch.manual_seed(1)
    q, k, v = (torch.randn(1, 1, 16, 8) for _ in range(3))  # 4 x 4 grid in window-major order, 2 x 2 windows
    local = local_attention(q, k, v, window=2)[0, 0]  # [16, 8]
    for w in range(4):
        rows = slice(4 * w, 4 * w + 4)
        torch.testing.assert_close(local[rows], _attention_by_hand(q[0, 0, rows], k[0, 0, rows], v[0, 0, rows]))
    glob = global_attention(q, k, v)[0, 0]
    torch.testing.assert_close(glob, _attention_by_hand(q[0, 0], k[0, 0], v[0, 0]))


def test_hybrid_attention_heads_match_hand_computation():
    torch.manual_seed(2)
    attn = HybridAttention(dim=16, num_heads=4, grid=4, window=2)
    x = torch.randn(1, 16, 16)  # row-major 4 x 4 grid
    with torch.no_grad():
        q, k, v = attn.qkv(x[0]).split(16, dim=-1)  # [16, 16] each
        heads = attn.heads(x)[0]  # [16, 16]
        window_of = [(r // 2) * 2 + c // 2 for r in range(4) for c in range(4)]
        for h in range(4):
            cols = slice(4 * h, 4 * h + 4)
            for token in range(16):
                keys = [j for j in range(16) if window_of[j] == window_of[token]] if h < 2 else list(range(16))
                expected = _attention_by_hand(q[token : token + 1, cols], k[keys, cols], v[keys, cols])[0]
                torch.testing.assert_close(heads[token, cols], expected)
        torch.nn.init.normal_(attn.proj.weight)  # it starts near zero (near-identity block); check the general case
        torch.nn.init.normal_(attn.proj.bias)
        pre_norm_heads = attn.heads(attn.norm(x))[0]  # [16, 16]
        torch.testing.assert_close(attn(x)[0], x[0] + attn.proj(pre_norm_heads))


@pytest.mark.parametrize(("grid", "window", "token", "inside", "outside"), [(4, 2, 0, 5, 2), (10, 5, 44, 0, 45)])
def test_local_branch_sees_its_window_only(grid, window, token, inside, outside):
    torch.manual_seed(0)
    attn = HybridAttention(dim=16, num_heads=4, grid=grid, window=window)
    x = torch.randn(2, grid * grid, 16)
    with torch.no_grad():
        base = attn.local_branch(x)
        for other, should_change in ((inside, True), (outside, False)):
            perturbed = x.clone()
            perturbed[:, other] += 3.0 * torch.randn(16)
            out = attn.local_branch(perturbed)
            changed = (out[:, token] - base[:, token]).abs().max().item()
            assert (changed > 1e-4) if should_change else (changed == 0.0), (other, changed)


def test_global_branch_sees_far_tokens():
    torch.manual_seed(0)
    attn = HybridAttention(dim=16, num_heads=4, grid=10, window=2)
    x = torch.randn(2, 100, 16)
    perturbed = x.clone()
    perturbed[:, 99] += 3.0 * torch.randn(16)  # the opposite corner of token 0 (not a uniform shift: the
    # block's pre-norm LayerNorm removes those by design)
    with torch.no_grad():
        change = (attn.global_branch(perturbed)[:, 0] - attn.global_branch(x)[:, 0]).abs().max()
        assert change > 1e-4
        # and through the whole block (LayerNorm, local + global heads, projection, residual); the projection
        # starts near zero by design, so give it unit-scale weights to see the wiring
        torch.nn.init.normal_(attn.proj.weight)
        assert (attn(perturbed)[:, 0] - attn(x)[:, 0]).abs().max() > 1e-4


# ------------------------------------------------------------------------------------------- action mask


def test_masked_actions_have_zero_probability_and_are_never_sampled():
    space = obs_space(k=4)
    net = make_net("full", space)
    obs = random_obs(space, batch=32, seed=4)
    obs["action_mask"][:16, 1:] = 0.0  # half the rows allow action 0 only
    many = {key: value.repeat(64, *([1] * (value.dim() - 1))) for key, value in obs.items()}  # 2048 rows
    allowed = many["action_mask"] > 0.5
    with torch.no_grad():
        logits, _ = net(many)
        probs = torch.softmax(logits, dim=-1)
        assert torch.all(probs[~allowed] == 0.0)
        torch.testing.assert_close(probs.sum(-1), torch.ones(len(probs)))
        torch.manual_seed(0)
        action, log_prob, _, _ = net.get_action_and_value(many)
    assert allowed.gather(1, action[:, None]).all()
    assert torch.isfinite(log_prob).all()
    assert len(set(action[allowed.sum(-1) > 8].tolist())) > 8  # a real sample, not a constant


def test_row_with_no_allowed_action_stays_finite():
    logits = torch.tensor([[0.3, -0.2, 1.0, 0.0] * 4, [0.5] * 16])
    mask = torch.zeros(2, 16)
    mask[0, [2, 7]] = 1.0
    masked = mask_logits(logits, mask)
    probs = torch.softmax(masked, dim=-1)
    assert torch.isfinite(probs).all()
    assert probs[0, [2, 7]].sum() == 1.0 and probs[0, 2] > probs[0, 7]
    torch.testing.assert_close(probs[1], torch.full((16,), 1 / 16))

    space = obs_space(k=4)
    net = make_net("de", space)
    obs = random_obs(space, batch=3)
    obs["action_mask"][1] = 0.0
    _, log_prob, entropy, _ = net.get_action_and_value(obs)
    assert torch.isfinite(log_prob).all() and torch.isfinite(entropy).all()


# --------------------------------------------------------------------------------------------- bad input


def test_wrong_observation_shapes_name_the_field():
    space = obs_space(k=4, P=4)
    net = make_net("full", space)
    obs = random_obs(space, batch=2)
    with pytest.raises(ObservationShapeError, match=r"'passengers' has shape \(2, 5, 12\), expected \(2, 4, 12\)"):
        net(dict(obs, passengers=torch.zeros(2, 5, 12)))
    with pytest.raises(ObservationShapeError, match=r"'sinr_patch' has shape \(2, 10, 10\)"):
        net(dict(obs, sinr_patch=torch.zeros(2, 10, 10)))
    with pytest.raises(ObservationShapeError, match=r"'action_mask' has shape \(1, 2, 16\), expected \(B, 16\)"):
        net({key: value[None] for key, value in obs.items()})  # [E, A, ...] not flattened
    with pytest.raises(ObservationShapeError, match=r"'visit_patch' has shape \(3, 4, 4\), expected \(2, 4, 4\)"):
        net(dict(obs, visit_patch=torch.zeros(3, 4, 4)))
    with pytest.raises(ObservationShapeError, match="lacks field 'others_mask'"):
        net({key: value for key, value in obs.items() if key != "others_mask"})


def test_state_must_match_the_critic():
    space = obs_space(k=4)
    obs = random_obs(space, batch=2)
    central = make_net("full", space, critic_state_dim=7)
    with pytest.raises(ValueError, match="critic_state_dim=7"):
        central(obs)
    with pytest.raises(ObservationShapeError, match=r"state has shape \(2, 6\), expected \(2, 7\)"):
        central(obs, state=torch.zeros(2, 6))
    assert central.masked_logits(obs).shape == (2, 16)  # the actor alone needs no state
    with pytest.raises(ValueError, match="no centralised critic"):
        make_net("full", space)(obs, state=torch.zeros(2, 7))


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (dict(variant="msha"), r"variant='msha' is unknown.*'le', 'de', 'de_msfea', 'full'"),
        (dict(local_window=1), r"local_window=1 makes 1 x 1 windows"),
        (dict(num_heads=1), r"num_heads=1 is too few"),
        (dict(d_model=60), r"d_model=60 must be >= 8 and a multiple of 2 \* num_heads = 8"),
        (dict(critic_state_dim=0), r"critic_state_dim=0 must be >= 1"),
        (dict(readout="max"), r"readout='max' is unknown.*'flatten', 'mean'"),
    ],
)
def test_bad_config_names_the_value(kwargs, pattern):
    with pytest.raises(ValueError, match=pattern):
        NetConfig(**kwargs)


def test_local_window_must_divide_the_patch():
    with pytest.raises(ValueError, match=r"local_window=3 does not divide the patch size k=10"):
        MSHAActorCritic(obs_space(k=10), NetConfig(local_window=3))
    MSHAActorCritic(obs_space(k=10), NetConfig(local_window=5))  # 5 x 5 windows on 10 x 10: fine
    MSHAActorCritic(obs_space(k=10), NetConfig(variant="de", local_window=3))  # no attention: not used


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_cuda_matches_cpu():
    space = obs_space(k=10)
    net = make_net("full", space)
    obs = random_obs(space, batch=16)
    with torch.no_grad():
        logits, value = net(obs)
        logits_c, value_c = net.cuda()({key: value.cuda() for key, value in obs.items()})
    torch.testing.assert_close(logits_c.cpu(), logits, atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(value_c.cpu(), value, atol=1e-4, rtol=1e-4)
