"""The building blocks of the MSHA network (:mod:`uamfleet.rl.networks`): CleanRL's initialisation and the
3-layer head, masked pooling and logits, the per-source encoders, the pointer pool, the grid readout, the
multi-source fusion and the hybrid (local-window + global) attention. Shapes: B agents, P passenger slots,
k x k patch cells.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn


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


def as_bool(mask: torch.Tensor) -> torch.Tensor:
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


def paired_map_features(first: MapEncoder, second: MapEncoder, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``torch.cat([first(a), second(b)], -1)`` for two k × k patches [B, k, k] → [B, k*k, 2C], computed as one
    grouped convolution per layer over the two patches stacked as channels, in channels-last memory.

    Why: the CNNs have 4 channels, too few for oneDNN's kernels to pay for their calls, and their backward was the
    largest single cost of a PPO update (reports/2026-12-03-benchmarks-history/README.md, "Where a PPO iteration's time
    goes"). One grouped channels-last convolution per layer does the two maps' work in less than half the time (a batch
    of 960: 9.5 ms forward and backward against 22.5 ms), with the same numbers to float rounding (tested; bit for bit
    with this machine's oneDNN for batches of 2 and more). A batch of one (a lone taxi's decision) keeps the two plain
    calls, which are faster there. Both encoders must be :class:`MapEncoder` of the same width; the parameters stay
    theirs, so checkpoints are unchanged.
    """
    if a.shape[0] < 2:
        return torch.cat([first(a), second(b)], dim=-1)  # [B, G, 2C]
    x = torch.stack([a, b], dim=1).contiguous(memory_format=torch.channels_last)  # [B, 2, k, k]
    for layer in (0, 2):  # conv, ReLU, conv, ReLU
        one, two = first.net[layer], second.net[layer]
        assert isinstance(one, nn.Conv2d) and isinstance(two, nn.Conv2d)
        assert one.bias is not None and two.bias is not None
        weight, bias = torch.cat([one.weight, two.weight]), torch.cat([one.bias, two.bias])  # [2C, C_in, 3, 3]
        x = F.relu(F.conv2d(x, weight, bias, padding=1, groups=2))  # [B, 2C, k, k] channels-last
    B, C2 = x.shape[:2]
    return x.permute(0, 2, 3, 1).reshape(B, -1, C2)  # [B, k*k, 2C] row-major cells (a view: channels-last)


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
    the "full" variant starts as "de_msfea" (plus a position embedding) and learns the attention on top (why not
    post-norm: reports/2026-12-03-results-history/README.md, "The recipe, and what made the difference", item 3).

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
