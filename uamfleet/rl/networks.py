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
cells, blind to position unless attention mixed in the position embedding) is kept for comparison (how the two
compare: reports/2026-12-03-results-history/README.md, "The recipe, and what made the difference", item 2).

Inputs are used as given (the trainer's ObservationNormalizer standardises the continuous fields; raw SINR
is in dB); masks are read as booleans (> 0.5), never rescaled.

Widths: tokens (taxi, passengers, other taxis) have ``d_model`` channels; each map CNN has ``d_model // 8``
(at least 4) and the fused grid ``d_model // 2``. The grid holds k² tokens per taxi (100 for k = 10), so its
width and the global heads' k² × k² scores, not the parameter count, set the cost of a batch.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces
from torch import nn
from torch.distributions import Categorical

from uamfleet.observe.observer import ObservationShapeError
from uamfleet.rl.encoders import (
    layer_init,
    mlp3,
    masked_mean,
    mask_logits,
    as_bool,
    TaxiEncoder,
    PassengerEncoder,
    MapEncoder,
    SetEncoder,
    PointerPool,
    GridReadout,
    multi_source_features,
    paired_map_features,
    MultiSourceFusion,
    window_order,
    local_attention,
    global_attention,
    HybridAttention,
)
from uamfleet.rl.heads import CLAIMED_BY_OTHER, LOOKAHEAD_RULE, PATH_TO_STOP, TOUR_VIA_STOP, StopHead
from uamfleet.types import DISPATCH_CLAIM_FEATURES, DISPATCH_CLAIMS_FIELD, NUM_HEADINGS


VARIANTS: tuple[str, ...] = ("le", "de", "de_msfea", "full")
ACTION_HEADS: tuple[str, ...] = ("headings", "stops")
STOP_PRIORS: tuple[str, ...] = ("tour", "nearest")
"""The stop head's prior measure of a stop (``stop_paths`` column): the shortest tour that flies to it first, or
the path to it alone."""
READOUTS: tuple[str, ...] = ("flatten", "mean")
NUM_ACTIONS = NUM_HEADINGS  # one logit per heading (the action mask's width)
NUM_ACTIONS_HOVER = NUM_HEADINGS + 1  # ... and the hover action's (HOVER_ACTION): hover_logit or hover_anytime
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
    # What the network reads beyond the fields every observation has (chosen here, never by which fields exist;
    # :func:`observed_inputs` derives them from a layout): each needs its observation field(s), see INPUT_FIELDS.
    stop_inputs: bool = False  # passenger rows also read their stop paths and an "actionable" flag
    rival_inputs: bool = False  # ... and what the other taxis offer for each stop (needs stop_inputs)
    claim_inputs: bool = False  # ... and the nearest-first matching's claims (needs rival_inputs)
    stop_hover: bool = False  # "stops": a hover component beside the free move (needs claim_inputs)
    # "stops" with stop_hover, for an env with the hover action (EnvConfig.hover_action): the hover component is
    # the logit of action 16 (HOVER_ACTION, stay in place) instead of mass on the hover heading: 17 logits
    hover_logit: bool = False
    lookahead_inputs: bool = False  # "stops": a learned correction from each heading's look-ahead (zero at first)
    # "stops" with lookahead_inputs: logits taken from each heading per move of its look-ahead excess, a fixed term
    # (not learned) that makes the untrained head fly the least look-ahead heading (:data:`LOOKAHEAD_RULE`); 0: none
    lookahead_rule: float = 0.0
    # "stops", for an env with the hover action: action 16's logit open at every step, stops open or not (a learned
    # bias from HOVER_START plus a zero-initialised linear map of the features; 17 logits, StopHead.with_anytime_hover);
    # with hover_logit the two hovers add up: hover_logit's where no stop is open, this one's at every step
    hover_anytime: bool = False
    # "stops": each passenger row also reads a dispatcher's claims on it (DISPATCH_CLAIM_FEATURES, the field
    # DISPATCH_CLAIMS_FIELD), which the policy supplies beside the observation (uamfleet.rl.fleet_claims), and each
    # stop's score gets a learned linear term of them; both zero at first (the network flies as without them)
    dispatch_claim_inputs: bool = False

    def __post_init__(self) -> None:
        self._check_head()
        self._check_inputs()
        self._check_attention()
        if self.readout not in READOUTS:
            raise ValueError(f"readout={self.readout!r} is unknown; use one of {READOUTS}.")
        if self.hidden < 1:
            raise ValueError(f"hidden={self.hidden} must be >= 1 (e.g. 128).")
        if self.critic_state_dim is not None and self.critic_state_dim < 1:
            raise ValueError(
                f"critic_state_dim={self.critic_state_dim} must be >= 1 (the env's state_space size) or None."
            )

    def _check_head(self) -> None:
        """The variant and the action head, and the combinations of them that cannot work."""
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

    def _check_inputs(self) -> None:
        """Each optional input needs the one before it (the observation has them only together)."""
        if self.variant == "le" and self.stop_inputs:
            raise ValueError(
                "stop_inputs=True adds columns to the passenger tokens, which the linear encoder ('le') does not "
                "make; use a designed variant ('de', 'de_msfea' or 'full') or stop_inputs=False."
            )
        if self.action_head == "stops" and not self.stop_inputs:
            raise ValueError(
                "action_head='stops' needs the stop features as inputs: NetConfig(stop_inputs=True) and an env "
                "built with EnvConfig(stop_features=True) (e.g. the 'berlin_instances' scenario)."
            )
        for name, needs in (("rival_inputs", "stop_inputs"), ("claim_inputs", "rival_inputs"),
                            ("stop_hover", "claim_inputs")):  # fmt: skip
            if getattr(self, name) and not getattr(self, needs):
                raise ValueError(f"{name}=True needs {needs}=True (the observation has them only together).")
        if self.dispatch_claim_inputs and self.action_head != "stops":
            raise ValueError(
                "dispatch_claim_inputs=True scores the stop head's stops by a dispatcher's claims: it needs "
                "action_head='stops' (and stop_inputs=True)."
            )
        self._check_stop_head_inputs()

    def _check_stop_head_inputs(self) -> None:
        """The inputs only the stop head reads (its hover, its look-ahead), and the look-ahead rule's weight."""
        if self.stop_hover and self.action_head != "stops":
            raise ValueError("stop_hover=True is a component of the stop head: it needs action_head='stops'.")
        if self.hover_logit and not self.stop_hover:
            raise ValueError(
                "hover_logit=True makes the stop head's hover component the hover action's logit: it needs "
                "stop_hover=True (action_head='stops' with claim inputs and the 'hover_heading_mask' field)."
            )
        if self.hover_anytime and self.action_head != "stops":
            raise ValueError(
                "hover_anytime=True mixes the hover action into the stop head's output: it needs action_head='stops'."
            )
        if self.lookahead_inputs and self.action_head != "stops":
            raise ValueError(
                "lookahead_inputs=True corrects the stop head's flight: it needs action_head='stops' (the 'headings' "
                "head reads no look-ahead)."
            )
        if not (math.isfinite(self.lookahead_rule) and self.lookahead_rule >= 0):
            raise ValueError(
                f"lookahead_rule={self.lookahead_rule} is logits per move of look-ahead: use a finite value >= 0 "
                f"(0: no rule term; {LOOKAHEAD_RULE:g}: the least look-ahead heading decides)."
            )
        if self.lookahead_rule > 0 and not self.lookahead_inputs:
            raise ValueError(
                f"lookahead_rule={self.lookahead_rule} weighs each heading's look-ahead: it needs "
                "lookahead_inputs=True (an env with EnvConfig(heading_lookahead=True))."
            )

    def _check_attention(self) -> None:
        """Heads, width and local windows of the hybrid attention."""
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


INPUT_FIELDS: dict[str, tuple[str, ...]] = {
    "stop_inputs": ("stop_paths", "stop_heading_mask"),
    "rival_inputs": ("stop_rivals",),
    "claim_inputs": ("stop_claims",),
    "stop_hover": ("hover_heading_mask",),
    "lookahead_inputs": ("heading_lookahead",),
}
"""The observation fields each optional input of :class:`NetConfig` reads."""


def observed_inputs(fields: Collection[str], variant: str = "full", action_head: str = "headings") -> dict[str, bool]:
    """The :class:`NetConfig` input flags that read every optional field among ``fields`` (a layout, a space's
    keys or a checkpoint's ``obs_shapes``) that a network of ``variant`` and ``action_head`` can read: for the
    trainer (from the training env's spec) and, once in the loader, for a checkpoint that predates the flags."""
    stops = variant != "le" and all(f in fields for f in INPUT_FIELDS["stop_inputs"])
    rivals = stops and "stop_rivals" in fields
    claims = rivals and "stop_claims" in fields
    hover = claims and action_head == "stops" and "hover_heading_mask" in fields
    lookahead = stops and action_head == "stops" and "heading_lookahead" in fields
    return {"stop_inputs": stops, "rival_inputs": rivals, "claim_inputs": claims, "stop_hover": hover,
            "lookahead_inputs": lookahead}  # fmt: skip


def missing_inputs(cfg: NetConfig, fields: Collection[str]) -> list[str]:
    """The observation fields ``cfg`` reads that ``fields`` lacks (empty: the observation fits)."""
    return [f for name, needed in INPUT_FIELDS.items() if getattr(cfg, name) for f in needed if f not in fields]


def check_observation_fits(shapes: Mapping[str, tuple[int, ...]], cfg: NetConfig) -> None:
    """ValueError naming what a network of ``cfg`` reads that an observation of ``shapes`` lacks or sizes
    otherwise, and the fix."""
    required = ("self", "history", "passengers", "sinr_patch", "visit_patch", "others", *MASK_FIELDS)
    missing = [key for key in required if key not in shapes]
    if missing:
        raise ValueError(f"observation_space lacks field(s) {missing}; build it with uamfleet's env.")
    missing = missing_inputs(cfg, shapes)
    if missing:
        asked = [name for name, fields in INPUT_FIELDS.items() if getattr(cfg, name) and set(fields) & set(missing)]
        raise ValueError(
            f"NetConfig({', '.join(f'{n}=True' for n in asked)}) reads observation field(s) {missing}, which this "
            "observation lacks: build the env with EnvConfig(stop_features=True) (stop_rivals / stop_claims for "
            "rivals, claims and hover), or turn those inputs off (observed_inputs(fields) gives what fits)."
        )
    k = shapes["sinr_patch"][0]
    if cfg.variant == "full" and k % cfg.local_window != 0:
        raise ValueError(
            f"local_window={cfg.local_window} does not divide the patch size k={k}; "
            f"use a divisor of {k} that is >= 2 (NetConfig(local_window=...))."
        )
    if shapes["action_mask"] != (NUM_ACTIONS,):
        raise ValueError(f"action_mask has shape {shapes['action_mask']}, expected ({NUM_ACTIONS},).")


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
        pax = torch.where(as_bool(obs["passenger_mask"]).unsqueeze(-1), obs["passengers"], zero)  # [B, P, F]
        others = torch.where(as_bool(obs["others_mask"]).unsqueeze(-1), obs["others"], zero)  # [B, O, 3]
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
        # with stop inputs, each passenger row also gets its path distances and an "actionable" flag
        self.stop_inputs, self.rival_inputs, self.claim_inputs = cfg.stop_inputs, cfg.rival_inputs, cfg.claim_inputs
        extra = shapes["stop_paths"][1] + 1 if self.stop_inputs else 0
        extra += shapes["stop_rivals"][1] if self.rival_inputs else 0  # a fleet: what the other taxis offer
        extra += shapes["stop_claims"][1] if self.claim_inputs else 0  # the nearest-first matching's claims
        self.dispatch_inputs = cfg.dispatch_claim_inputs
        extra += len(DISPATCH_CLAIM_FEATURES) if self.dispatch_inputs else 0  # a dispatcher's claims, last
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
        released = as_bool(obs["passenger_mask"])  # [B, P]
        taxi = self.taxi(obs["history"], obs["self"])  # [B, D]
        rows = obs["passengers"]  # [B, P, F]
        if self.stop_inputs:
            actionable = as_bool(obs["stop_heading_mask"]).any(-1, keepdim=True).to(rows.dtype)  # [B, P, 1]
            parts = [rows, obs["stop_paths"], actionable] + ([obs["stop_rivals"]] if self.rival_inputs else [])
            if self.claim_inputs:
                parts.append(obs["stop_claims"].to(rows.dtype))
            if self.dispatch_inputs:
                parts.append(obs[DISPATCH_CLAIMS_FIELD].to(rows.dtype))
            rows = torch.cat(parts, dim=-1)  # [B, P, F + 3 (+ 2 rivals + 2 claims)]
        pax = self.passengers(rows, released)  # [B, P, D]
        maps = paired_map_features(self.sinr_cnn, self.visit_cnn, obs["sinr_patch"], obs["visit_patch"])  # [B, G, 2C]
        others = self.others(obs["others"], as_bool(obs["others_mask"]))  # [B, D]
        grid = maps  # [B, G, 2C] for "de"
        if self.fusion is not None:
            tokens = torch.cat([taxi.unsqueeze(1), pax], dim=1)  # [B, 1 + P, D]
            valid = torch.cat([torch.ones_like(released[:, :1]), released], dim=1)  # [B, 1 + P] the taxi always
            grid = self.fusion(tokens, valid, maps)  # [B, G, Dg]
        if self.attention is not None:
            grid = self.attention(grid + self.pos_embed)  # [B, G, Dg]
        pointed = self.pointer(taxi, pax, released)  # [B, D]
        return torch.cat([taxi, pointed, others, self.readout(grid)], dim=-1), pax  # [B, 3D + readout], [B, P, D]


# ---------------------------------------------------------------------------------------------- the policy


class MSHAActorCritic(nn.Module):
    """Shared actor-critic over one taxi's observation; ``critic_state_dim`` makes the critic centralised."""

    def __init__(self, observation_space: spaces.Dict, cfg: NetConfig = NetConfig()) -> None:
        super().__init__()
        self.cfg = cfg
        self.shapes = {key: tuple(sub.shape or ()) for key, sub in observation_space.spaces.items()}
        check_observation_fits(self.shapes, cfg)
        self.torso: LinearTorso | DesignedTorso = (
            LinearTorso(self.shapes, cfg.d_model) if cfg.variant == "le" else DesignedTorso(self.shapes, cfg)
        )
        features = self.torso.out_dim
        self.actor = mlp3(features, cfg.hidden, NUM_ACTIONS, out_std=0.01)
        self.critic = mlp3(cfg.critic_state_dim or features, cfg.hidden, 1, out_std=1.0)
        self.stop_head: StopHead | None = None
        if cfg.action_head == "stops":  # NetConfig guarantees a designed torso with stop inputs
            self.stop_head = StopHead(
                features, cfg.d_model, cfg.hidden, free_move=cfg.stop_free_move, claims=cfg.claim_inputs,
                hover=cfg.stop_hover, residual=cfg.heading_residual, lookahead=cfg.lookahead_inputs,
                hover_logit=cfg.hover_logit, lookahead_rule=cfg.lookahead_rule, hover_anytime=cfg.hover_anytime,
                dispatch=cfg.dispatch_claim_inputs,
            )  # fmt: skip

    @property
    def num_actions(self) -> int:
        """Logits per row: the 16 headings, and the hover action (HOVER_ACTION) with ``NetConfig.hover_logit`` or
        ``NetConfig.hover_anytime``."""
        return NUM_ACTIONS_HOVER if self.cfg.hover_logit or self.cfg.hover_anytime else NUM_ACTIONS

    def _actor(self, obs: dict[str, torch.Tensor], with_residual: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
        """(masked logits [B, 16 or 17], torso features [B, F]); ``with_residual=False``: the stop head's prior
        alone. Action 16 (``hover_logit``, ``hover_anytime``) is never masked: the hover is always allowed."""
        if self.stop_head is None:
            features = self.torso(obs)  # [B, F]
            return mask_logits(self.actor(features), obs["action_mask"]), features
        assert isinstance(self.torso, DesignedTorso)
        features, tokens = self.torso.encode(obs)  # [B, F], [B, P, D]
        free = mask_logits(self.actor(features), obs["action_mask"])  # [B, 16]
        measure = TOUR_VIA_STOP if self.cfg.stop_prior == "tour" else PATH_TO_STOP
        prior = obs["stop_paths"][..., measure]  # [B, P] map sides: the prior's measure of each stop
        claimed = as_bool(obs["stop_claims"][..., CLAIMED_BY_OTHER]) if self.stop_head.claims else None  # [B, P]
        hover = obs["hover_heading_mask"] if self.stop_head.hovers else None  # [B, 16]
        look = obs["heading_lookahead"] if self.stop_head.lookahead else None  # [B, 16]
        dispatch = obs[DISPATCH_CLAIMS_FIELD] if self.cfg.dispatch_claim_inputs else None  # [B, P, 4]
        logp = self.stop_head(
            features, tokens, obs["stop_heading_mask"], free, prior, claimed, hover, with_residual, look, dispatch
        )  # [B, 16 (+ 1)]
        allowed = obs["action_mask"]  # [B, 16]
        if self.cfg.hover_logit:
            allowed = torch.cat([allowed, torch.ones_like(allowed[:, :1])], dim=-1)  # [B, 17]
        masked = mask_logits(logp, allowed)  # [B, 16 (+ 1)]
        if self.cfg.hover_anytime:  # mixed in after the mask: the headings keep their masked probabilities' ratios
            return self.stop_head.with_anytime_hover(masked, features), features  # [B, 17]
        return masked, features

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
        """The actor alone (no state needed, even with a centralised critic): masked logits [B, 16] (17 with the hover
        action's, :attr:`num_actions`)."""
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
        dist, value = self.policy_and_value(obs, state)
        action = dist.sample() if action is None else action.long()  # [B]
        return action, dist.log_prob(action), dist.entropy(), value

    def policy_and_value(
        self, obs: dict[str, torch.Tensor], state: torch.Tensor | None = None
    ) -> tuple[Categorical, torch.Tensor]:
        """The action distribution over the masked logits, and the value [B]: what the PPO update differentiates
        (the log-probability and entropy of its actions, and a KL term that needs every action's probability)."""
        logits, value = self(obs, state)  # [B, 16], [B]
        return Categorical(logits=logits), value


def obs_to_torch(obs: dict[str, np.ndarray], device: torch.device | str) -> dict[str, torch.Tensor]:
    """numpy fields [B, ...] → float32 tensors on ``device`` (masks stay 0/1 values; the network reads them
    as booleans, never rescaled)."""
    return {key: torch.as_tensor(np.asarray(value), dtype=torch.float32, device=device) for key, value in obs.items()}


# The building blocks live in uamfleet.rl.encoders; they stay importable from here. The stop head lives in
# uamfleet.rl.heads.
__all__ = [
    "ACTION_HEADS", "INPUT_FIELDS", "MASK_FIELDS", "NUM_ACTIONS", "NUM_ACTIONS_HOVER", "READOUTS", "STOP_PRIORS",
    "VARIANTS",
    "DesignedTorso", "GridReadout", "HybridAttention", "LinearTorso", "MSHAActorCritic", "MapEncoder",
    "MultiSourceFusion", "NetConfig", "PassengerEncoder", "PointerPool", "SetEncoder", "TaxiEncoder",
    "as_bool", "check_observation_fits", "global_attention", "layer_init", "local_attention", "mask_logits",
    "masked_mean", "missing_inputs", "mlp3", "multi_source_features", "obs_to_torch", "observed_inputs",
    "paired_map_features", "window_order",
]  # fmt: skip
