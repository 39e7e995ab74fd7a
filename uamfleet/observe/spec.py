"""The one spec of the observation: which fields a config observes, their shapes, dtypes, bounds, column names and
how a learner treats each (:func:`observation_layout`).

Everything else reads it: the observer allocates its arrays and builds its ``spaces.Dict`` from it, the kernels
write columns through the ``uamfleet.types`` indices named by its ``columns``, the normaliser reads ``kind``, a
policy learns its shapes from it (no env needed), and ``docs/rules.md`` and the ``parallel_env`` docstring are
tested against it (``tests/observe/test_layout.py``). A field's presence depends on config flags only, never on the
fleet size (the fleet size sets the length of ``others``).

A pure function of the config: no world, distance table or env is built.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from gymnasium import spaces

from uamfleet.config import EnvConfig
from uamfleet.sim.world import PATCH_CLIP_DB, PATCH_PAD_DB
from uamfleet.types import (
    HISTORY_FEATURES,
    LOOKAHEAD_CLIP,
    NUM_HEADINGS,
    OTHER_FEATURES,
    PASSENGER_FEATURES,
    SELF_FEATURES,
    STOP_CLAIM_FEATURES,
    STOP_PATH_CLIP,
    STOP_PATH_FEATURES,
    STOP_RIVAL_FEATURES,
)

FieldKind = Literal["feature", "set", "mask", "raw"]
FIELD_KINDS: tuple[str, ...] = ("feature", "set", "mask", "raw")
"""How a learner treats a field:

- ``"feature"``: continuous, normalised with running statistics per element;
- ``"set"``: as a feature, but its rows (first axis) are a set of entities of any number (passengers, other taxis):
  rows whose ``row_mask`` is 0 stay exactly zero, and statistics resized to another number of rows are pooled;
- ``"mask"``: int8 0/1 (allowed headings, real rows), never normalised;
- ``"raw"``: passed through unchanged: path distances in map sides (already O(1), compared across rows) and 0/1
  claims.
"""


@dataclass(frozen=True)
class FieldSpec:
    """One observation field, per taxi (the core adds the batch axes ``[E, A]`` in front of ``shape``)."""

    shape: tuple[int, ...]
    dtype: str  # numpy dtype name: "float32" or "int8"
    low: float
    high: float
    columns: tuple[str, ...] | None  # names of the last axis (uamfleet.types); None for grids and heading masks
    kind: FieldKind
    row_mask: str | None = None  # kind "set": the mask field of its rows

    def space(self) -> spaces.Box:
        return spaces.Box(self.low, self.high, self.shape, np.dtype(self.dtype))


Layout = dict[str, FieldSpec]

_F32, _I8 = "float32", "int8"


def observation_layout(cfg: EnvConfig) -> Layout:
    """The fields ``cfg`` observes, in the order the observer returns them (docs/rules.md "Observation").

    Always: ``self``, ``history``, ``passengers`` / ``passenger_mask``, ``sinr_patch``, ``visit_patch``,
    ``others`` / ``others_mask`` (``max(A - 1, 1)`` rows: one masked row for a lone taxi), ``action_mask``.
    ``stop_features``: ``stop_paths``, ``stop_heading_mask``; with ``stop_rivals`` or ``stop_claims`` also
    ``stop_rivals``; ``stop_claims``: ``stop_claims``, ``hover_heading_mask``; ``heading_lookahead``: the field of
    that name.

    The passenger axis P (of ``passengers``, ``passenger_mask`` and the stop fields, :data:`PASSENGER_AXIS_FIELDS`)
    is ``cfg.passenger_window`` when set (each taxi's nearest active requests, :mod:`uamfleet.observe.window`), else
    every passenger of the episode (``cfg.num_passengers``)."""
    return _layout_of(cfg, cfg.observed_passengers)


def computed_layout(cfg: EnvConfig) -> Layout:
    """The layout the observer computes before the passenger window (``EnvConfig.passenger_window``) picks each
    taxi's rows: :func:`observation_layout` with a row for every passenger of the state (``cfg.num_passengers``);
    the same as it without a window."""
    return _layout_of(cfg, cfg.num_passengers)


def _layout_of(cfg: EnvConfig, P: int) -> Layout:
    rivals = cfg.stop_features and (cfg.stop_rivals or cfg.stop_claims)
    return _layout(P, cfg.history_len, cfg.patch_size, max(cfg.num_taxis - 1, 1),
                   cfg.stop_features, rivals, cfg.stop_claims, cfg.stop_features and cfg.heading_lookahead)  # fmt: skip


def _layout(
    P: int, H: int, k: int, others: int, stops: bool, rivals: bool, claims: bool, lookahead: bool = False
) -> Layout:
    """The layout of P passenger slots, H history steps, k x k patches, ``others`` rows and the stop fields."""
    layout: Layout = {
        "self": FieldSpec((len(SELF_FEATURES),), _F32, -1.0, 1.0, SELF_FEATURES, "feature"),
        "history": FieldSpec((H, len(HISTORY_FEATURES)), _F32, -2.0, 2.0, HISTORY_FEATURES, "feature"),
        "passengers": FieldSpec(
            (P, len(PASSENGER_FEATURES)), _F32, -2.0, 2.0, PASSENGER_FEATURES, "set", "passenger_mask"
        ),
        "passenger_mask": FieldSpec((P,), _I8, 0, 1, None, "mask"),
        "sinr_patch": FieldSpec((k, k), _F32, PATCH_PAD_DB, PATCH_CLIP_DB, None, "feature"),
        "visit_patch": FieldSpec((k, k), _F32, 0.0, 1.0, None, "feature"),
        "others": FieldSpec((others, len(OTHER_FEATURES)), _F32, -2.0, 2.0, OTHER_FEATURES, "set", "others_mask"),
        "others_mask": FieldSpec((others,), _I8, 0, 1, None, "mask"),
        "action_mask": FieldSpec((NUM_HEADINGS,), _I8, 0, 1, None, "mask"),
    }
    if stops:
        layout["stop_paths"] = FieldSpec(
            (P, len(STOP_PATH_FEATURES)), _F32, 0.0, STOP_PATH_CLIP, STOP_PATH_FEATURES, "raw"
        )
        layout["stop_heading_mask"] = FieldSpec((P, NUM_HEADINGS), _I8, 0, 1, None, "mask")
    if rivals:
        layout["stop_rivals"] = FieldSpec(
            (P, len(STOP_RIVAL_FEATURES)), _F32, 0.0, STOP_PATH_CLIP, STOP_RIVAL_FEATURES, "raw"
        )
    if claims:
        layout["stop_claims"] = FieldSpec((P, len(STOP_CLAIM_FEATURES)), _I8, 0, 1, STOP_CLAIM_FEATURES, "raw")
        layout["hover_heading_mask"] = FieldSpec((NUM_HEADINGS,), _I8, 0, 1, None, "mask")
    if lookahead:
        layout["heading_lookahead"] = FieldSpec((NUM_HEADINGS,), _F32, 0.0, LOOKAHEAD_CLIP, None, "raw")
    return layout


_EVERY_FIELD = _layout(1, 1, 1, 1, stops=True, rivals=True, claims=True, lookahead=True)
PASSENGER_AXIS_FIELDS: tuple[str, ...] = ("passengers", "passenger_mask", "stop_paths", "stop_heading_mask",
                                          "stop_rivals", "stop_claims")  # fmt: skip
"""The fields whose first axis is the passenger axis (row p: one passenger): the passenger window picks their rows
together (``tests/observe/test_window.py`` checks this is every field whose shape follows P)."""
ALL_FIELDS: tuple[str, ...] = tuple(_EVERY_FIELD)
"""Every field any config observes, in :func:`observation_layout`'s order."""
FIELD_KIND: dict[str, FieldKind] = {name: spec.kind for name, spec in _EVERY_FIELD.items()}
"""The kind of each field by name (a kind never depends on the config): for readers that know a field's name but
not its config, e.g. a normaliser built from a checkpoint's shapes."""


def field_kind(name: str) -> FieldKind:
    """The kind of observation field ``name``; ValueError for a name no config observes."""
    return _field(name).kind


def field_row_mask(name: str) -> str | None:
    """The mask field of the rows of field ``name`` (kind ``"set"``), else None."""
    return _field(name).row_mask


def _field(name: str) -> FieldSpec:
    if name not in _EVERY_FIELD:
        raise ValueError(f"{name!r} is not an observation field; the fields are {list(ALL_FIELDS)}.")
    return _EVERY_FIELD[name]


def observation_space(layout: Mapping[str, FieldSpec]) -> spaces.Dict:
    """The ``spaces.Dict`` of one taxi's observation (Gymnasium sorts its keys)."""
    return spaces.Dict({name: spec.space() for name, spec in layout.items()})


def layout_shapes(layout: Mapping[str, FieldSpec]) -> dict[str, tuple[int, ...]]:
    return {name: spec.shape for name, spec in layout.items()}


def layout_differences(expected: Mapping[str, FieldSpec], got: Mapping[str, FieldSpec]) -> list[str]:
    """One line per field that differs between two layouts (missing, extra, or which attributes differ), sorted by
    field name; empty when they agree."""
    lines = []
    for name in sorted(set(expected) | set(got)):
        want, have = expected.get(name), got.get(name)
        if want is None or have is None:
            lines.append(f"{name!r}: {'only in the second' if want is None else 'only in the first'} layout")
            continue
        diffs = [
            f"{attr} {getattr(want, attr)!r} vs {getattr(have, attr)!r}"
            for attr in FieldSpec.__dataclass_fields__
            if getattr(want, attr) != getattr(have, attr)
        ]
        if diffs:
            lines.append(f"{name!r}: " + ", ".join(diffs))
    return lines


def layout_to_dict(layout: Mapping[str, FieldSpec]) -> dict[str, dict[str, Any]]:
    """Plain lists, strings and floats (for a checkpoint loaded with ``torch.load(weights_only=True)`` or JSON)."""
    return {name: _spec_to_dict(spec) for name, spec in layout.items()}


def _spec_to_dict(spec: FieldSpec) -> dict[str, Any]:
    columns = None if spec.columns is None else list(spec.columns)
    return {"shape": list(spec.shape), "dtype": spec.dtype, "low": float(spec.low), "high": float(spec.high),
            "columns": columns, "kind": spec.kind, "row_mask": spec.row_mask}  # fmt: skip


def layout_from_dict(data: Mapping[str, Mapping[str, Any]]) -> Layout:
    """The inverse of :func:`layout_to_dict`; ValueError naming the field for an entry that is not a field spec."""
    layout: Layout = {}
    for name, entry in data.items():
        try:
            columns = entry["columns"]
            spec = FieldSpec(
                shape=tuple(int(n) for n in entry["shape"]), dtype=str(entry["dtype"]), low=float(entry["low"]),
                high=float(entry["high"]), columns=None if columns is None else tuple(str(c) for c in columns),
                kind=entry["kind"], row_mask=entry.get("row_mask"),
            )  # fmt: skip
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f"observation field {name!r}: {dict(entry)!r} is not a field spec ({err}).") from None
        if spec.kind not in FIELD_KINDS:
            raise ValueError(f"observation field {name!r} has kind {spec.kind!r}; the kinds are {FIELD_KINDS}.")
        layout[str(name)] = spec
    return layout


__all__ = [
    "ALL_FIELDS",
    "FIELD_KIND",
    "FIELD_KINDS",
    "PASSENGER_AXIS_FIELDS",
    "FieldKind",
    "FieldSpec",
    "Layout",
    "computed_layout",
    "field_kind",
    "field_row_mask",
    "layout_differences",
    "layout_from_dict",
    "layout_shapes",
    "layout_to_dict",
    "observation_layout",
    "observation_space",
]
