"""The MSHA actor-critic (paper §IV-B) and its ablation variants (paper Table III).

One shared policy for every taxi: the observation is already relative to the observing taxi, so the trainer
flattens ``[env, taxi]`` into one batch axis ``B`` and the network sees ``{field: [B, ...]}``.

Variants (:data:`VARIANTS`):

- ``"le"``: a linear encoder of each flattened source (unreleased passengers and absent taxis zeroed first).
- ``"de"``: designed encoders: history → LSTM, passengers → transformer encoder with a key-padding mask,
  SINR and visit patches → two separate CNNs keeping the k × k grid, other taxis → masked DeepSets. The head
  reads the taxi token, the passenger tokens pooled by attention with the taxi token as query (a "pointer" to
  the passenger that matters now; unreleased rows excluded), the map grid and the other taxis.
- ``"de_msfea"``: + multi-source features: the token mean (taxi + released passengers) broadcast over the
  grid and concatenated with both maps' features, then a per-cell FFN; this fused grid replaces the maps'.
- ``"full"``: + hybrid attention fusion over the k × k fused tokens (local-window heads + global heads).

Each variant adds one module to the one before, so the ablation measures that module. The grid (maps or fused
tokens) is read out by a linear layer over the flattened k × k cells (``readout="flatten"``, the default),
which keeps *where* on the patch a feature is: the direction of a no-fly area decides the heading. The
paper's ``f_output ∈ R^{1×C}`` after a linear layer admits this reading; ``readout="mean"`` (a mean over the
cells, blind to position unless attention mixed in the position embedding) is kept for comparison: with it
the designed variants stalled at 2 of 4 passengers on Berlin P4 where the linear encoder learned the tour.

Inputs are used as given (the trainer's ObservationNormalizer standardises the continuous fields; raw SINR
is in dB); masks are read as booleans (> 0.5), never rescaled.

Widths: tokens (taxi, passengers, other taxis) have ``d_model`` channels; each map CNN has ``d_model // 8``
(at least 4) and the fused grid ``d_model // 2``. The grid holds k² tokens per taxi (100 for k = 10), so its
width and the global heads' k² × k² scores, not the parameter count, set the cost of a batch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces
from torch import nn
from torch.distributions import Categorical

from uamfleet.env.observer import ObservationShapeError
from uamfleet.types import NUM_HEADINGS, STOP_CLAIM_FEATURES, STOP_PATH_FEATURES

TOUR_VIA_STOP = STOP_PATH_FEATURES.index("tour_via_stop")
PATH_TO_STOP = STOP_PATH_FEATURES.index("path_to_stop")
CLAIMED_BY_OTHER = STOP_CLAIM_FEATURES.index("claimed_by_other")

VARIANTS: tuple[str, ...] = ("le", "de", "de_msfea", "full")
ACTION_HEADS: tuple[str, ...] = ("headings", "stops")
STOP_PRIORS: tuple[str, ...] = ("tour", "nearest")
"""The stop head's prior measure of a stop (``stop_paths`` column): the shortest tour that flies to it first, or
the path to it alone."""
READOUTS: tuple[str, ...] = ("flatten", "mean")
NUM_ACTIONS = NUM_HEADINGS  # one logit per heading
MASK_FIELDS: tuple[str, ...] = ("passenger_mask", "others_mask", "action_mask")


@dataclass(frozen=True)
class NetConfig:
    """Network hyper-parameters; checked on construction."""

    variant: str = "full"
    d_model: int = 64  # token / feature width
    num_heads: int = 4  # split into num_heads // 2 local heads and the rest global
    local_window: int = 2  # side of the non-overlapping windows of the local heads; must divide the patch size k
    hidden: int = 128  # width of the 3-layer actor and critic MLPs
    readout: str = "flatten"  # grid → head features: "flatten" (linear over the k*k cells) or "mean" (over cells)
    critic_state_dim: int | None = None  # set: the critic reads the global state [B, S] (MAPPO)
    action_head: str = "headings"  # "stops": a pointer over the stops, each flown along its progress heading
    stop_free_move: bool = False  # "stops": also a free move beside the stops (else only when no stop is actionable)
    stop_prior: str = "tour"  # "stops": the prior prefers the shortest tour via a stop, or "nearest" stop
    heading_residual: bool = False  # "stops": learned per-heading logits on top of the stop mixture (zero at first)

    def __post_init__(self) -> None:
        if self.stop_prior not in STOP_PRIORS:
            raise ValueError(f"stop_prior={self.stop_prior!r} is unknown; use one of {STOP_PRIORS}.")
        if self.action_head not in ACTION_HEADS:
            raise ValueError(f"action_head={self.action_head!r} is unknown; use one of {ACTION_HEADS}.")
        if self.heading_residual and self.action_head != "stops":
            raise ValueError(
                "heading_residual=True adds learned logits to the stop head's prior; it needs action_head='stops' "
                "(the 'headings' head already chooses every heading freely)."
            )
        if self.action_head == "stops" and self.variant == "le":
            raise ValueError(
                "action_head='stops' points at passenger tokens, which the linear encoder ('le') does not make; "
                "use a designed variant ('de', 'de_msfea' or 'full')."
            )
        if self.variant not in VARIANTS:
            raise ValueError(f"variant={self.variant!r} is unknown; use one of {VARIANTS}.")
        if self.num_heads < 2:
            raise ValueError(
                f"num_heads={self.num_heads} is too few: the hybrid attention needs at least one local and one "
                "global head; use num_heads >= 2 (e.g. 4 = 2 local + 2 global)."
            )
        if self.d_model < 8 or self.d_model % (2 * self.num_heads) != 0:
            raise ValueError(
                f"d_model={self.d_model} must be >= 8 and a multiple of 2 * num_heads = {2 * self.num_heads} "
                "(the fused grid has d_model // 2 channels split over num_heads heads); e.g. d_model=64."
            )
        if self.local_window < 2:
            raise ValueError(
                f"local_window={self.local_window} makes 1 x 1 windows, where local attention is an identity; "
                "use a window side >= 2 that divides the patch size (e.g. 2 or 5 for a 10 x 10 patch)."
            )
        if self.readout not in READOUTS:
            raise ValueError(f"readout={self.readout!r} is unknown; use one of {READOUTS}.")
        if self.hidden < 1:
            raise ValueError(f"hidden={self.hidden} must be >= 1 (e.g. 128).")
        if self.critic_state_dim is not None and self.critic_state_dim < 1:
            raise ValueError(
                f"critic_state_dim={self.critic_state_dim} must be >= 1 (the env's state_space size) or None."
            )


def layer_init(layer: nn.Linear, std: float = math.sqrt(2), bias: float = 0.0) -> nn.Linear:
    """Orthogonal weights and constant bias, as CleanRL."""
    nn.init.orthogonal_(layer.weight, std)
    nn.init.constant_(layer.bias, bias)
    return layer


def mlp3(in_dim: int, hidden: int, out_dim: int, out_std: float) -> nn.Sequential:
    """The paper's 3-layer head; CleanRL init (sqrt 2 inside, ``out_std`` on the output layer)."""
    return nn.Sequential(
        layer_init(nn.Linear(in_dim, hidden)),
        nn.Tanh(),
        layer_init(nn.Linear(hidden, hidden)),
        nn.Tanh(),
        layer_init(nn.Linear(hidden, out_dim), std=out_std),
    )


def masked_mean(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of ``x`` [B, N, ...] over the rows where ``mask`` [B, N] (bool) holds; zero where none does."""
    m = mask.reshape(*mask.shape, *([1] * (x.dim() - 2)))  # [B, N, 1, ...]
    # where, not multiply: garbage (even inf / NaN) in a masked row must not leak through 0 * x.
    total = torch.where(m, x, x.new_zeros(())).sum(1)  # [B, ...]
    count = mask.sum(1).clamp(min=1).to(x.dtype)  # [B]
    return total / count.reshape(-1, *([1] * (total.dim() - 1)))  # [B, ...]


def mask_logits(logits: torch.Tensor, action_mask: torch.Tensor) -> torch.Tensor:
    """Disallowed actions get the most negative finite logit, so their probability is exactly 0.

    A row with no allowed action (cannot come from the env) is left unmasked rather than made all -inf (NaN).
    """
    allowed = action_mask if action_mask.dtype == torch.bool else action_mask > 0.5  # [B, 16]
    allowed = allowed | ~allowed.any(-1, keepdim=True)  # [B, 16]
    return logits.masked_fill(~allowed, torch.finfo(logits.dtype).min)  # [B, 16]


def _as_bool(mask: torch.Tensor) -> torch.Tensor:
    return mask if mask.dtype == torch.bool else mask > 0.5


# ----------------------------------------------------------------------------------------------- encoders


class TaxiEncoder(nn.Module):
    """History (newest first in the observation) → LSTM over oldest → newest; the last output is the token."""

    def __init__(self, history_features: int, self_features: int, d_model: int) -> None:
        super().__init__()
        self.lstm = nn.LSTM(history_features + self_features, d_model, batch_first=True)

    def forward(self, history: torch.Tensor, own: torch.Tensor) -> torch.Tensor:
        steps = history.flip(1)  # [B, H, 3] oldest first, so the final state summarises up to now
        own = own.unsqueeze(1).expand(-1, steps.shape[1], -1)  # [B, H, 4]
        out, _ = self.lstm(torch.cat([steps, own], dim=-1))  # [B, H, D]
        return out[:, -1]  # [B, D]


class PassengerEncoder(nn.Module):
    """Passenger rows → transformer encoder; unreleased rows are keys nobody attends to."""

    def __init__(self, features: int, d_model: int, num_heads: int) -> None:
        super().__init__()
        self.embed = nn.Linear(features, d_model)
        layer = nn.TransformerEncoderLayer(
            d_model, num_heads, dim_feedforward=2 * d_model, dropout=0.0, batch_first=True, norm_first=True
        )
        # enable_nested_tensor=False: one code path in training and inference (same numbers, no warning).
        self.encoder = nn.TransformerEncoder(layer, num_layers=1, enable_nested_tensor=False)

    def forward(self, passengers: torch.Tensor, released: torch.Tensor) -> torch.Tensor:
        """passengers [B, P, F], released [B, P] bool → tokens [B, P, D] (rows not released are meaningless)."""
        rows = torch.where(released.unsqueeze(-1), passengers, passengers.new_zeros(()))  # [B, P, F]
        padding = ~released  # [B, P] True = ignore as a key; the raw boolean mask, never rescaled
        # With no released passenger every key would be masked and softmax would give NaN: let such rows attend
        # to their (zeroed) rows instead; the caller drops those tokens anyway.
        padding = padding & released.any(-1, keepdim=True)  # [B, P]
        return self.encoder(self.embed(rows), src_key_padding_mask=padding)  # [B, P, D]


class MapEncoder(nn.Module):
    """A k × k patch → k × k × C features (padding keeps the grid; paper §IV-B1, v_R and v_E)."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(1, channels, 3, padding=1),
            nn.ReLU(),
            nn.Conv2d(channels, channels, 3, padding=1),
            nn.ReLU(),
        )

    def forward(self, patch: torch.Tensor) -> torch.Tensor:
        out = self.net(patch.unsqueeze(1))  # [B, C, k, k]
        return out.flatten(2).transpose(1, 2)  # [B, k*k, C] row-major grid tokens


class SetEncoder(nn.Module):
    """DeepSets over the other taxis: masked mean of a per-row MLP; zero when there is no other taxi."""

    def __init__(self, features: int, d_model: int) -> None:
        super().__init__()
        self.phi = nn.Sequential(nn.Linear(features, d_model), nn.ReLU(), nn.Linear(d_model, d_model), nn.ReLU())

    def forward(self, rows: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        return masked_mean(self.phi(rows), present)  # [B, D]


class PointerPool(nn.Module):
    """Attention pooling of the passenger tokens with the taxi token as the query: [B, P, D] → [B, D].

    One query (the taxi) over the released rows only; a taxi with no released passenger gets zeros. Unlike a
    plain mean, it can single out one passenger (the nearest pick-up, the drop-off on board).
    """

    def __init__(self, d_model: int) -> None:
        super().__init__()
        self.query = nn.Linear(d_model, d_model)
        self.scale = d_model**-0.5

    def forward(self, taxi: torch.Tensor, tokens: torch.Tensor, released: torch.Tensor) -> torch.Tensor:
        # where, not multiply: garbage (even NaN) in a masked row must not leak through 0 * x
        tokens = torch.where(released.unsqueeze(-1), tokens, tokens.new_zeros(()))  # [B, P, D]
        scores = torch.einsum("bd,bpd->bp", self.query(taxi), tokens) * self.scale  # [B, P]
        scores = scores.masked_fill(~released, torch.finfo(scores.dtype).min)  # [B, P]
        weights = torch.where(released, torch.softmax(scores, dim=-1), scores.new_zeros(()))  # [B, P]; none → 0
        return torch.einsum("bp,bpd->bd", weights, tokens)  # [B, D]


class GridReadout(nn.Module):
    """Grid tokens [B, G, C] → head features: a linear layer + ReLU over the flattened cells ([B, out]), which
    keeps each feature's position on the patch, or the mean over cells ([B, C]) for ``readout="mean"``."""

    def __init__(self, cells: int, channels: int, out_dim: int, mode: str) -> None:
        super().__init__()
        self.proj = nn.Linear(cells * channels, out_dim) if mode == "flatten" else None
        self.out_dim = out_dim if mode == "flatten" else channels

    def forward(self, grid: torch.Tensor) -> torch.Tensor:
        if self.proj is None:
            return grid.mean(1)  # [B, C]
        return F.relu(self.proj(grid.flatten(1)))  # [B, out]


# ------------------------------------------------------------------------------------ multi-source features


def multi_source_features(tokens: torch.Tensor, token_mask: torch.Tensor, maps: torch.Tensor) -> torch.Tensor:
    """Paper §IV-B1 (e_UP, f_EUP, f_RUP, f_M): every token [B, N, D] broadcast over the grid and concatenated
    with the map features [B, G, C] (G = k²), averaged over the valid tokens (``token_mask`` [B, N]) →
    [B, G, D + C].

    The map channels are the same for every token, so the mean of the concatenations is the concatenation of
    the token mean with the maps; computing it that way avoids a [B, N, G, D + C] tensor. (The paper's two
    copies of the token mean, one beside each map, are merged: the next linear layer sees the same thing.)
    """
    pooled = masked_mean(tokens, token_mask)  # [B, D]
    grid = pooled.unsqueeze(1).expand(-1, maps.shape[1], -1)  # [B, G, D]
    return torch.cat([grid, maps], dim=-1)  # [B, G, D + C]


class MultiSourceFusion(nn.Module):
    """Multi-source features followed by a per-cell FFN → fused grid tokens [B, G, Dg].

    The ReLU matters: the grid mean of a *linear* map of [token mean, map features] would just be the
    pooled concatenation of the "de" variant, with no token-map interaction.
    """

    def __init__(self, token_dim: int, map_dim: int, out_dim: int) -> None:
        super().__init__()
        self.token_dim = token_dim
        self.proj = nn.Linear(token_dim + map_dim, out_dim)

    def forward(self, tokens: torch.Tensor, token_mask: torch.Tensor, maps: torch.Tensor) -> torch.Tensor:
        # = relu(proj(multi_source_features(...))) with the weight split by input block: the token part is
        # the same in every cell, so it is projected once per sample instead of once per cell.
        w_token, w_map = self.proj.weight.split([self.token_dim, maps.shape[-1]], dim=1)
        pooled = masked_mean(tokens, token_mask)  # [B, D]
        from_token = F.linear(pooled, w_token, self.proj.bias)  # [B, Dg]
        from_maps = F.linear(maps, w_map)  # [B, G, Dg]
        return F.relu(from_maps + from_token.unsqueeze(1))  # [B, G, Dg]


# ------------------------------------------------------------------------------------ hybrid attention


def window_order(grid: int, window: int) -> torch.Tensor:
    """Permutation [grid²] taking row-major grid tokens to window-major order: window after window
    (row-major over windows), the window × window tokens of each contiguous (row-major inside)."""
    n = grid // window
    cells = torch.arange(grid * grid).reshape(n, window, n, window)  # [row block, row, col block, col]
    return cells.permute(0, 2, 1, 3).reshape(-1)  # [grid²]


def local_attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, window: int) -> torch.Tensor:
    """Attention inside each window (paper §IV-B2, Atten_i and h_local); tokens in :func:`window_order`.

    q, k, v: [B, h, G, d] → [B, h, G, d]; token i attends only to the window² tokens of its own window;
    scale 1 / sqrt(d_k), d_k the head width as in the paper (the original code's 1 / sqrt(32) was a bug).
    """
    B, h, G, d = q.shape
    win = window * window
    qw, kw, vw = (t.reshape(B * h, G // win, win, d) for t in (q, k, v))  # [B*h, n_win, w², d] each
    out = F.scaled_dot_product_attention(qw, kw, vw, scale=d**-0.5)  # [B*h, n_win, w², d]
    return out.reshape(B, h, G, d)  # [B, h, G, d]


def global_attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Attention over all tokens: q, k, v [B, h, G, d] → [B, h, G, d]; scale 1 / sqrt(d)."""
    return F.scaled_dot_product_attention(q, k, v, scale=q.shape[-1] ** -0.5)  # [B, h, G, d]


class HybridAttention(nn.Module):
    """Self-attention over the k × k fused tokens with the heads split in two groups (paper §IV-B2): the
    first num_heads // 2 attend inside non-overlapping window × window blocks, the others over all k²
    tokens; outputs concatenated, projected and added back (pre-norm residual: ``x + proj(heads(norm(x)))``).

    The output projection starts near zero (orthogonal, gain 0.01), so the block starts close to the identity:
    the "full" variant starts as "de_msfea" (plus a position embedding) and learns the attention on top. With
    the post-norm form ``norm(x + proj(heads(x)))`` the full model stalled at 2 of 4 passengers on Berlin P4
    for 100k agent-steps where "de_msfea" had found the optimal tour after 70k.

    Tokens come in and go out in row-major grid order; inside, they are put in window-major order once so
    that every window is a contiguous block (attention, projections and LayerNorm do not care about order).
    """

    order: torch.Tensor  # [G] row-major → window-major
    inverse: torch.Tensor  # [G] window-major → row-major

    def __init__(self, dim: int, num_heads: int, grid: int, window: int) -> None:
        super().__init__()
        if window < 2 or grid % window != 0:
            raise ValueError(
                f"local_window={window} must be >= 2 and divide the patch size k={grid}; use a divisor of {grid}."
            )
        if dim % num_heads != 0:
            raise ValueError(f"dim={dim} must be a multiple of num_heads={num_heads}.")
        self.window = window
        self.num_heads = num_heads
        self.local_heads = num_heads // 2
        self.head_dim = dim // num_heads
        self.qkv = nn.Linear(dim, 3 * dim)
        self.proj = nn.Linear(dim, dim)
        layer_init(self.proj, std=0.01)  # near-identity block at initialisation (see the class docstring)
        self.norm = nn.LayerNorm(dim)
        order = window_order(grid, window)  # [G]
        self.register_buffer("order", order, persistent=False)
        self.register_buffer("inverse", torch.argsort(order), persistent=False)

    def _heads(self, x: torch.Tensor) -> torch.Tensor:
        """x [B, G, dim] window-major → local and global head outputs [B, G, dim] (local heads first)."""
        B, G, dim = x.shape
        qkv = self.qkv(x).reshape(B, G, 3, self.num_heads, self.head_dim).permute(2, 0, 3, 1, 4)  # [3, B, h, G, d]
        q, k, v = qkv.unbind(0)  # [B, h, G, d] each
        L = self.local_heads
        local = local_attention(q[:, :L], k[:, :L], v[:, :L], self.window)  # [B, hL, G, d]
        glob = global_attention(q[:, L:], k[:, L:], v[:, L:])  # [B, hG, G, d]
        return torch.cat([local, glob], dim=1).transpose(1, 2).reshape(B, G, dim)  # [B, G, dim]

    def heads(self, x: torch.Tensor) -> torch.Tensor:
        """The concatenated head outputs [B, G, dim] (row-major), before the output projection: channels
        [:local_heads * head_dim] are the local branch, the rest the global branch. For tests and probing."""
        return self._heads(x[:, self.order])[:, self.inverse]  # [B, G, dim]

    def local_branch(self, x: torch.Tensor) -> torch.Tensor:
        """The local heads' output [B, G, local_heads * head_dim] for row-major tokens x [B, G, dim]."""
        return self.heads(x)[..., : self.local_heads * self.head_dim]  # [B, G, hL * d]

    def global_branch(self, x: torch.Tensor) -> torch.Tensor:
        """The global heads' output [B, G, (num_heads - local_heads) * head_dim] for row-major tokens x."""
        return self.heads(x)[..., self.local_heads * self.head_dim :]  # [B, G, hG * d]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        xw = x[:, self.order]  # [B, G, dim] window-major
        out = xw + self.proj(self._heads(self.norm(xw)))  # [B, G, dim]
        return out[:, self.inverse]  # [B, G, dim] row-major


# ---------------------------------------------------------------------------------------------- torsos


class LinearTorso(nn.Module):
    """Variant "le": one linear layer (+ ReLU) per flattened source, concatenated."""

    def __init__(self, shapes: dict[str, tuple[int, ...]], d_model: int) -> None:
        super().__init__()

        def size(key: str) -> int:
            return int(np.prod(shapes[key]))

        self.taxi = nn.Linear(size("self") + size("history"), d_model)
        self.passengers = nn.Linear(size("passengers"), d_model)
        self.sinr = nn.Linear(size("sinr_patch"), d_model)
        self.visit = nn.Linear(size("visit_patch"), d_model)
        self.others = nn.Linear(size("others"), d_model)
        self.out_dim = 5 * d_model

    def forward(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        zero = obs["self"].new_zeros(())
        pax = torch.where(_as_bool(obs["passenger_mask"]).unsqueeze(-1), obs["passengers"], zero)  # [B, P, F]
        others = torch.where(_as_bool(obs["others_mask"]).unsqueeze(-1), obs["others"], zero)  # [B, O, 3]
        parts = [
            self.taxi(torch.cat([obs["self"], obs["history"].flatten(1)], dim=-1)),  # [B, D]
            self.passengers(pax.flatten(1)),  # [B, D]
            self.sinr(obs["sinr_patch"].flatten(1)),  # [B, D]
            self.visit(obs["visit_patch"].flatten(1)),  # [B, D]
            self.others(others.flatten(1)),  # [B, D]
        ]
        return F.relu(torch.cat(parts, dim=-1))  # [B, 5D]


class DesignedTorso(nn.Module):
    """Variants "de", "de_msfea" and "full": the designed encoders; "de_msfea" fuses the tokens into the map
    grid (MSFea), "full" adds hybrid attention over it (HAF). Output: [taxi token, passengers pooled by the taxi's
    query, other taxis, grid readout]."""

    def __init__(self, shapes: dict[str, tuple[int, ...]], cfg: NetConfig) -> None:
        super().__init__()
        D = cfg.d_model
        C = max(D // 8, 4)  # channels per map CNN
        Dg = D // 2  # fused grid width: k² tokens per sample make this the costly part
        k = shapes["sinr_patch"][0]
        self.taxi = TaxiEncoder(shapes["history"][1], shapes["self"][0], D)
        # with stop features, each passenger row also gets its path distances and an "actionable" flag
        self.stop_inputs = "stop_paths" in shapes and "stop_heading_mask" in shapes
        extra = shapes["stop_paths"][1] + 1 if self.stop_inputs else 0
        self.rival_inputs = self.stop_inputs and "stop_rivals" in shapes  # a fleet: what the other taxis offer
        extra += shapes["stop_rivals"][1] if self.rival_inputs else 0
        self.claim_inputs = self.rival_inputs and "stop_claims" in shapes  # the nearest-first matching's claims
        extra += shapes["stop_claims"][1] if self.claim_inputs else 0
        self.passengers = PassengerEncoder(shapes["passengers"][1] + extra, D, cfg.num_heads)
        self.sinr_cnn = MapEncoder(C)
        self.visit_cnn = MapEncoder(C)  # a separate CNN: SINR and visit ratio are different physical fields
        self.others = SetEncoder(shapes["others"][1], D)
        self.pointer = PointerPool(D)
        self.fusion: MultiSourceFusion | None = None
        self.attention: HybridAttention | None = None
        if cfg.variant == "de":
            self.readout = GridReadout(k * k, 2 * C, D, cfg.readout)  # the two maps' CNN features
        else:
            self.fusion = MultiSourceFusion(D, 2 * C, Dg)
            self.readout = GridReadout(k * k, Dg, D, cfg.readout)  # the fused grid
        if cfg.variant == "full":
            self.attention = HybridAttention(Dg, cfg.num_heads, k, cfg.local_window)
            self.pos_embed = nn.Parameter(torch.randn(k * k, Dg) * 0.02)  # [G, Dg] learned, one per cell
        self.out_dim = 3 * D + self.readout.out_dim

    def forward(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.encode(obs)[0]

    def encode(self, obs: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        """(features [B, 3D + readout], passenger tokens [B, P, D])."""
        released = _as_bool(obs["passenger_mask"])  # [B, P]
        taxi = self.taxi(obs["history"], obs["self"])  # [B, D]
        rows = obs["passengers"]  # [B, P, F]
        if self.stop_inputs:
            actionable = _as_bool(obs["stop_heading_mask"]).any(-1, keepdim=True).to(rows.dtype)  # [B, P, 1]
            parts = [rows, obs["stop_paths"], actionable] + ([obs["stop_rivals"]] if self.rival_inputs else [])
            if self.claim_inputs:
                parts.append(obs["stop_claims"].to(rows.dtype))
            rows = torch.cat(parts, dim=-1)  # [B, P, F + 3 (+ 2 rivals + 2 claims)]
        pax = self.passengers(rows, released)  # [B, P, D]
        maps = torch.cat([self.sinr_cnn(obs["sinr_patch"]), self.visit_cnn(obs["visit_patch"])], dim=-1)  # [B, G, 2C]
        others = self.others(obs["others"], _as_bool(obs["others_mask"]))  # [B, D]
        grid = maps  # [B, G, 2C] for "de"
        if self.fusion is not None:
            tokens = torch.cat([taxi.unsqueeze(1), pax], dim=1)  # [B, 1 + P, D]
            valid = torch.cat([torch.ones_like(released[:, :1]), released], dim=1)  # [B, 1 + P] the taxi always
            grid = self.fusion(tokens, valid, maps)  # [B, G, Dg]
        if self.attention is not None:
            grid = self.attention(grid + self.pos_embed)  # [B, G, Dg]
        pointed = self.pointer(taxi, pax, released)  # [B, D]
        return torch.cat([taxi, pointed, others, self.readout(grid)], dim=-1), pax  # [B, 3D + readout], [B, P, D]


# ------------------------------------------------------------------------------------------ the stop head

NOT_THIS = -1e4  # log-weight of "no": exp() is 0 in float32, yet finite, so no NaN reaches a gradient
NEARNESS_INIT = 20.0
"""Initial weight of the stop head's prior, per map side of tour: on Berlin (3.3 km) a stop whose tour is 330 m
shorter starts with 2 more logits (e^2 = 7.4 times the probability)."""
HOVER_LEAD = 2.0
"""Initial lead, in logits, of the stop head's hover component over its free move: an idle taxi starts by
hovering (7.4 times as likely as moving freely)."""
PRIOR_FLOOR = -12.0
"""With ``heading_residual``, the stop mixture's log-probabilities are floored here before the learned residual
is added: a heading the prior rules out (log-probability -1e4) stays within reach of a residual of a dozen logits,
and with zero residuals the policy keeps the prior's greedy choice and all but e^-12 of its probabilities."""
CLAIM_INIT = 8.0
"""Initial logits taken from a stop that the nearest-first matching gives to another taxi (``stop_claims``): about
the tour prior of 1.3 km more (Berlin), and enough that a taxi whose every stop is claimed starts by waiting."""


class StopHead(nn.Module):
    """``action_head="stops"``: the policy as a mixture over the taxi's actionable stops and a free move.

    The env marks, per actionable stop, the heading that makes most progress along its feasible path
    (``stop_heading_mask``, one-hot). Each stop p gets a score from its passenger token and the taxi's features;
    a "free" component gets one from the features alone and spreads its weight over the allowed headings by the
    actor's logits. Then ``pi(h) = sum_p w_p [h = heading_p] + w_free * pi_free(h)`` with ``w = softmax(scores)``:
    still one categorical distribution over the 16 headings (the env and PPO are unchanged), but choosing a stop
    is one decision instead of learning the path to it.

    Each stop's score starts from a prior, ``-nearness * (measure - the best stop's)``. With
    ``NetConfig.stop_prior="tour"`` the measure is ``tour_via_stop`` (``stop_paths[..., 2]``, map sides, passed
    to the network unnormalised): the shortest tour through every known stop that flies to this one first. So
    the untrained policy already flies that tour and keeps flying to the stop it chose; ``nearness`` (initially
    :data:`NEARNESS_INIT`, learned) and the learned part of the score then move it off that order where the
    return says so. Without a prior the untrained policy picks a stop afresh every step and dithers between them
    (episodes of ~370 steps against ~90 for flying to the nearest stop, in a first run); with the nearest stop's
    distance as the prior, PPO stayed at the nearest-stop heuristic's TD for 1 M agent-steps (validation mean
    10,416 m against its 10,470 m). With ``stop_prior="nearest"`` the measure is ``path_to_stop``: the fleet's
    choice, since one taxi's tour through every waiting passenger of a fleet is not its tour.

    In a fleet whose observation has ``stop_claims`` (``claims=True``), a waiting passenger that the nearest-first
    matching of free taxis gives to *another* taxi starts :data:`CLAIM_INIT` logits lower (``claim_weight``,
    learned), and the free component is also open when every actionable stop of the taxi is claimed by others
    (it carries nobody and no passenger is left for it): the taxi may then wait instead of chasing another
    taxi's passenger. Without claims every taxi of a fleet flew to some stop, so idle taxis converged on the last
    waiting passengers and flew in convoy (18.7 separation violations per episode against greedy's 1.5).
    With ``hover=True`` (the observation has ``hover_heading_mask``, the heading back to where the taxi was a step
    ago) a hover component opens with the free move and starts :data:`HOVER_LEAD` logits ahead of it: an idle
    taxi then hovers about a point, as the dispatchers' idle taxis do, instead of wandering into the others (with
    claims but no hover, idle taxis drifted together: most of the separation violations left).

    ``free_move=False`` (the default) gives the free component weight only when the taxi has no actionable
    stop (nothing released, or everyone delivered): the policy then chooses stops only. With ``free_move=True``
    it is always a component (starting at ``free_bias``), so the policy may wait or reposition; in a first run
    on Berlin instances its weight grew (the entropy bonus favours spreading over all headings) and episodes got
    longer, from 78 to 250 steps in 3 iterations, so it is off by default.

    ``residual=True`` (``NetConfig.heading_residual``) lets the policy choose its flight: learned per-heading
    logits (each stop's from its hidden row, weighted by that stop's mixture weight, plus one from the features)
    are added to the mixture's log-probabilities floored at :data:`PRIOR_FLOOR`. They start at zero, so the
    untrained head flies as the prior; the order of the known stops still comes from the exact tour prior.
    """

    def __init__(
        self, features: int, d_model: int, hidden: int, free_bias: float = -2.0, free_move: bool = False,
        claims: bool = False, hover: bool = False, residual: bool = False,
    ) -> None:  # fmt: skip
        super().__init__()
        self.free_move, self.claims, self.hovers, self.residual = free_move, claims, hover, residual
        if residual:  # the flight beyond the prior: per-heading logits, zero at first (the prior unchanged)
            self.residual_per_stop = layer_init(nn.Linear(hidden, NUM_HEADINGS), std=0.0)
            self.residual_free = layer_init(nn.Linear(features, NUM_HEADINGS), std=0.0)
        if claims:  # only then: checkpoints of heads without claims keep their exact parameter set
            self.log_claim_weight = nn.Parameter(torch.tensor(math.log(CLAIM_INIT)))
        if hover:  # a "hover" component beside the free move, HOVER_LEAD logits ahead of it at first
            self.hover = layer_init(nn.Linear(features, 1), std=0.01, bias=free_bias + HOVER_LEAD)
        self.from_features = nn.Linear(features, hidden)
        self.from_token = nn.Linear(d_model, hidden, bias=False)
        self.score = layer_init(nn.Linear(hidden, 1), std=0.01)
        self.free = layer_init(nn.Linear(features, 1), std=0.01, bias=free_bias)
        self.log_nearness = nn.Parameter(torch.tensor(math.log(NEARNESS_INIT)))

    def forward(
        self, features: torch.Tensor, tokens: torch.Tensor, heading_mask: torch.Tensor, free_logits: torch.Tensor,
        path_to_stop: torch.Tensor | None = None, claimed_by_other: torch.Tensor | None = None,
        hover_mask: torch.Tensor | None = None, with_residual: bool = True,
    ) -> torch.Tensor:  # fmt: skip
        """features [B, F], tokens [B, P, D], heading_mask [B, P, 16], free_logits [B, 16] (masked), path_to_stop
        [B, P] (map sides; None: no prior), claimed_by_other [B, P] bool (with ``claims``), hover_mask [B, 16]
        one-hot (with ``hover``) → log pi [B, 16]; with ``residual`` (and ``with_residual``) unnormalised logits:
        the mixture's log-probabilities floored at :data:`PRIOR_FLOOR` plus the learned per-heading residual."""
        onehot = _as_bool(heading_mask)  # [B, P, 16]
        actionable = onehot.any(-1)  # [B, P]
        hidden = torch.tanh(self.from_features(features).unsqueeze(1) + self.from_token(tokens))  # [B, P, H]
        scores = self.score(hidden).squeeze(-1)  # [B, P]
        if path_to_stop is not None:  # relative to the nearest stop: only the free move's weight sees the shift
            nearest = path_to_stop.masked_fill(~actionable, math.inf).amin(-1, keepdim=True)  # [B, 1]
            extra = torch.where(actionable, path_to_stop - nearest, 0.0)  # [B, P] >= 0
            scores = scores - self.log_nearness.exp() * extra
        open_stop = actionable  # [B, P] the stops that keep the free component closed
        if self.claims:
            if claimed_by_other is None:
                raise ValueError("this stop head reads claims: pass claimed_by_other [B, P] (obs 'stop_claims').")
            scores = scores - self.log_claim_weight.exp() * claimed_by_other.to(scores.dtype)
            open_stop = actionable & ~claimed_by_other
        scores = scores.masked_fill(~actionable, NOT_THIS)  # [B, P]
        free_score = self.free(features)  # [B, 1]
        if not self.free_move:  # only when there is no stop to fly to (that no other taxi is matched with)
            free_score = free_score.masked_fill(open_stop.any(-1, keepdim=True), NOT_THIS)
        idle = [free_score]
        if self.hovers:
            if hover_mask is None:
                raise ValueError("this stop head hovers: pass hover_mask [B, 16] (obs 'hover_heading_mask').")
            hover_at = _as_bool(hover_mask)  # [B, 16] one-hot (all zero: no move allowed)
            closed = open_stop.any(-1, keepdim=True) | ~hover_at.any(-1, keepdim=True)  # [B, 1]
            idle.append(self.hover(features).masked_fill(closed, NOT_THIS))
        weights = torch.log_softmax(torch.cat([scores, *idle], dim=-1), dim=-1)  # [B, P + 1 (+ 1)]
        P = scores.shape[-1]
        per_stop = weights[:, :P, None] + torch.where(onehot, 0.0, NOT_THIS)  # [B, P, 16]
        free = weights[:, P : P + 1, None] + torch.log_softmax(free_logits, dim=-1).unsqueeze(1)  # [B, 1, 16]
        parts = [per_stop, free]
        if self.hovers:
            parts.append(weights[:, P + 1 :, None] + torch.where(hover_at, 0.0, NOT_THIS).unsqueeze(1))  # [B, 1, 16]
        logp = torch.logsumexp(torch.cat(parts, dim=1), dim=1)  # [B, 16] log-probabilities
        if not (self.residual and with_residual):
            return logp
        # each stop's own flight correction (from its hidden row), weighted by how likely that stop is chosen
        per_stop = torch.einsum("bp,bph->bh", weights[:, :P].exp(), self.residual_per_stop(hidden))  # [B, 16]
        return logp.clamp(min=PRIOR_FLOOR) + per_stop + self.residual_free(features)  # [B, 16]


# ---------------------------------------------------------------------------------------------- the policy


class MSHAActorCritic(nn.Module):
    """Shared actor-critic over one taxi's observation; ``critic_state_dim`` makes the critic centralised."""

    def __init__(self, observation_space: spaces.Dict, cfg: NetConfig = NetConfig()) -> None:
        super().__init__()
        self.cfg = cfg
        self.shapes = {key: tuple(sub.shape or ()) for key, sub in observation_space.spaces.items()}
        required = ("self", "history", "passengers", "sinr_patch", "visit_patch", "others", *MASK_FIELDS)
        missing = [key for key in required if key not in self.shapes]
        if missing:
            raise ValueError(f"observation_space lacks field(s) {missing}; build it with uamfleet's env.")
        k = self.shapes["sinr_patch"][0]
        if cfg.variant == "full" and k % cfg.local_window != 0:
            raise ValueError(
                f"local_window={cfg.local_window} does not divide the patch size k={k}; "
                f"use a divisor of {k} that is >= 2 (NetConfig(local_window=...))."
            )
        if self.shapes["action_mask"] != (NUM_ACTIONS,):
            raise ValueError(f"action_mask has shape {self.shapes['action_mask']}, expected ({NUM_ACTIONS},).")
        self.torso: LinearTorso | DesignedTorso = (
            LinearTorso(self.shapes, cfg.d_model) if cfg.variant == "le" else DesignedTorso(self.shapes, cfg)
        )
        features = self.torso.out_dim
        self.actor = mlp3(features, cfg.hidden, NUM_ACTIONS, out_std=0.01)
        self.critic = mlp3(cfg.critic_state_dim or features, cfg.hidden, 1, out_std=1.0)
        self.stop_head: StopHead | None = None
        if cfg.action_head == "stops":
            if not (isinstance(self.torso, DesignedTorso) and self.torso.stop_inputs):
                raise ValueError(
                    "action_head='stops' needs the stop features in the observation ('stop_paths', "
                    "'stop_heading_mask'): build the env with EnvConfig(stop_features=True), e.g. the "
                    "'berlin_instances' scenario."
                )
            self.stop_head = StopHead(
                features, cfg.d_model, cfg.hidden, free_move=cfg.stop_free_move, claims=self.torso.claim_inputs,
                hover=self.torso.claim_inputs and "hover_heading_mask" in self.shapes, residual=cfg.heading_residual,
            )  # fmt: skip

    def _actor(self, obs: dict[str, torch.Tensor], with_residual: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
        """(masked logits [B, 16], torso features [B, F]); ``with_residual=False``: the stop head's prior alone."""
        if self.stop_head is None:
            features = self.torso(obs)  # [B, F]
            return mask_logits(self.actor(features), obs["action_mask"]), features
        assert isinstance(self.torso, DesignedTorso)
        features, tokens = self.torso.encode(obs)  # [B, F], [B, P, D]
        free = mask_logits(self.actor(features), obs["action_mask"])  # [B, 16]
        measure = TOUR_VIA_STOP if self.cfg.stop_prior == "tour" else PATH_TO_STOP
        prior = obs["stop_paths"][..., measure]  # [B, P] map sides: the prior's measure of each stop
        claimed = _as_bool(obs["stop_claims"][..., CLAIMED_BY_OTHER]) if self.stop_head.claims else None  # [B, P]
        hover = obs["hover_heading_mask"] if self.stop_head.hovers else None  # [B, 16]
        logp = self.stop_head(
            features, tokens, obs["stop_heading_mask"], free, prior, claimed, hover, with_residual
        )  # [B, 16]
        return mask_logits(logp, obs["action_mask"]), features

    def check(self, obs: dict[str, torch.Tensor]) -> int:
        """Raise :class:`ObservationShapeError` unless every field is [B, *space shape]; return B."""
        batch: int | None = None
        for key, expected in self.shapes.items():
            if key not in obs:
                raise ObservationShapeError(
                    f"observation lacks field {key!r}; expected fields {sorted(self.shapes)} with one batch axis."
                )
            shape = tuple(obs[key].shape)
            if len(shape) != 1 + len(expected) or shape[1:] != expected or (batch is not None and shape[0] != batch):
                want = "(" + ", ".join(str(n) for n in (batch if batch is not None else "B", *expected)) + ")"
                raise ObservationShapeError(
                    f"observation field {key!r} has shape {shape}, expected {want} (one batch axis); flatten "
                    "[env, taxi] into one axis and use an env of the config the network was built for."
                )
            batch = shape[0]
        assert batch is not None
        return batch

    def _check_state(self, state: torch.Tensor | None, batch: int) -> None:
        S = self.cfg.critic_state_dim
        if S is None:
            if state is not None:
                raise ValueError(
                    "state was given but the network has no centralised critic; build it with "
                    "NetConfig(critic_state_dim=...) or pass state=None."
                )
            return
        if state is None:
            raise ValueError(
                f"the critic is centralised (critic_state_dim={S}) and needs state [B, {S}]; pass state=... "
                "(for the actor alone use masked_logits(obs))."
            )
        if tuple(state.shape) != (batch, S):
            raise ObservationShapeError(f"state has shape {tuple(state.shape)}, expected ({batch}, {S}).")

    def masked_logits(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        """The actor alone (no state needed, even with a centralised critic): masked logits [B, 16]."""
        self.check(obs)
        return self._actor(obs)[0]  # [B, 16]

    def prior_logits(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        """The stop head's mixture without the learned heading residual: masked logits [B, 16] (the same as
        :meth:`masked_logits` for a network without ``heading_residual``)."""
        self.check(obs)
        return self._actor(obs, with_residual=False)[0]  # [B, 16]

    def forward(
        self, obs: dict[str, torch.Tensor], state: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """obs: per-taxi fields [B, ...]; state: global state [B, S] for a centralised critic.

        Returns (masked logits [B, 16], value [B]).
        """
        self._check_state(state, self.check(obs))
        logits, features = self._actor(obs)  # [B, 16], [B, F]
        critic_in = features if state is None else state  # [B, F] or [B, S]
        value = self.critic(critic_in).squeeze(-1)  # [B]
        return logits, value

    def get_action_and_value(
        self,
        obs: dict[str, torch.Tensor],
        action: torch.Tensor | None = None,
        state: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """CleanRL's call: (action [B] long, log-prob [B], entropy [B], value [B]); samples if action is None."""
        logits, value = self(obs, state)  # [B, 16], [B]
        dist = Categorical(logits=logits)
        action = dist.sample() if action is None else action.long()  # [B]
        return action, dist.log_prob(action), dist.entropy(), value


def obs_to_torch(obs: dict[str, np.ndarray], device: torch.device | str) -> dict[str, torch.Tensor]:
    """numpy fields [B, ...] → float32 tensors on ``device`` (masks stay 0/1 values; the network reads them
    as booleans, never rescaled)."""
    return {key: torch.as_tensor(np.asarray(value), dtype=torch.float32, device=device) for key, value in obs.items()}
