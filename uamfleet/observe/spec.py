"""The one spec of the observation: which fields a config observes, their shapes, dtypes, bounds, column names and
how a learner treats each (:func:`observation_layout`).

Everything else reads it: the observer allocates its arrays and builds its ``spaces.Dict`` from it, the kernels
write columns through the ``uamfleet.types`` indices named by its ``columns``, the normaliser reads ``kind``, a
policy learns its shapes from it (no env needed), and ``docs/rules.md`` and the ``parallel_env`` docstring are
tested against it (``tests/observe/test_layout.py``). A field's presence depends on config flags only, never on the
fleet size (the fleet size sets the length of ``others``).

What a policy reads is an :class:`ObserverSpec` (the fields, their sizes, the planner-derived components);
:meth:`ObserverSpec.layout` gives its layout in a world and :meth:`ObserverSpec.reads` says in one line what of a
world it cannot read. Pure functions of the config and the spec: no world, distance table or env is built.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from gymnasium import spaces

from uamfleet.checks import MAX_HISTORY_LEN, MAX_PASSENGERS, MAX_PATCH_SIZE, MAX_TAXIS, MAX_TIME_LIMIT_STEPS
from uamfleet.config import (
    NEEDS_STOP_FEATURES,
    PATCH_SIZE_FIX,
    ConfigError,
    EnvConfig,
    WorldConfig,
    check_integer,
    check_number,
    lookahead_depth_message,
    passenger_window_fix,
)
from uamfleet.checks import check_flag
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


@dataclass(frozen=True)
class StopsSpec:
    """The stop features (``stop_paths``, ``stop_heading_mask``): with ``rivals`` also ``stop_rivals``; with
    ``claims`` also ``stop_rivals``, ``stop_claims`` and ``hover_heading_mask`` (docs/rules.md "Observation")."""

    rivals: bool = False
    claims: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "rivals", check_flag("stop_rivals", self.rivals))
        object.__setattr__(self, "claims", check_flag("stop_claims", self.claims))


@dataclass(frozen=True)
class LookaheadSpec:
    """The ``heading_lookahead`` field: each heading's move and the tour after it (``depth=1``), or its move, the
    best second move and the tour after both (``depth=2``). Reads the stop features' tours."""

    depth: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.depth, bool) or self.depth not in (1, 2):
            raise ConfigError(lookahead_depth_message(self.depth))
        object.__setattr__(self, "depth", int(self.depth))


@dataclass(frozen=True)
class ObserverSpec:
    """What a policy reads of a world: the observation's fields and their sizes, independent of the world's rules.

    ``ObserverSpec()`` is the paper's observation: ``self``, ``history`` (3 steps), ``passengers`` (every passenger
    row of the world), 10 x 10 ``sinr_patch`` / ``visit_patch``, ``others``, ``action_mask``; no stop fields.

    - ``passenger_window``: K passenger rows per taxi (its nearest active requests); None: a fixed passenger axis.
    - ``slots_per_taxi``: without a window, the rows read are ``ceil(slots_per_taxi x the world's taxis)`` (rows
      beyond the world's are padding); None: the world's own rows.
    - ``time_scale_steps``: the denominator of the time feature; None: the world's time limit.
    - ``stops`` (:class:`StopsSpec`), ``lookahead`` (:class:`LookaheadSpec`, needs ``stops``): the planner-derived
      fields.
    - ``hover``: the policy's action set includes the hover action (16).
    - ``fleet_rows``: the policy reads the other taxis by position, this many rows (a world of ``fleet_rows + 1``
      taxis); None: as a set, any fleet.

    Checked on construction (:class:`ConfigError`, one line); what needs the world is :meth:`reads`.
    """

    history_len: int = 3
    patch_size: int = 10
    passenger_window: int | None = None
    slots_per_taxi: float | None = None
    time_scale_steps: int | None = None
    stops: StopsSpec | None = None
    lookahead: LookaheadSpec | None = None
    hover: bool = False
    fleet_rows: int | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("history_len", check_integer("history_len", self.history_len, 1, MAX_HISTORY_LEN))
        put("patch_size", check_integer("patch_size", self.patch_size, 1, MAX_PATCH_SIZE, fix=PATCH_SIZE_FIX))
        if self.passenger_window is not None:
            put("passenger_window", check_integer("passenger_window", self.passenger_window, 1, MAX_PASSENGERS,
                                                  fix=" (or None: every request)"))  # fmt: skip
        if self.slots_per_taxi is not None:
            put("slots_per_taxi", check_number("slots_per_taxi (or None: the world's rows)", self.slots_per_taxi,
                                               positive=True))  # fmt: skip
        if self.time_scale_steps is not None:
            put("time_scale_steps", check_integer("time_scale_steps (or None: the world's time limit)",
                                                  self.time_scale_steps, 1, MAX_TIME_LIMIT_STEPS))  # fmt: skip
        if self.fleet_rows is not None:
            put("fleet_rows", check_integer("fleet_rows (or None: any fleet)", self.fleet_rows, 0, MAX_TAXIS - 1))
        put("hover", check_flag("hover", self.hover))
        for name, cls in (("stops", StopsSpec), ("lookahead", LookaheadSpec)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, cls):
                raise ConfigError(f"{name}={value!r} must be a {cls.__name__} or None, e.g. {cls.__name__}().")
        if self.lookahead is not None and self.stops is None:
            raise ConfigError(NEEDS_STOP_FEATURES["heading_lookahead"])

    def rows(self, world: WorldConfig) -> int:
        """Passenger rows of each taxi's observation in ``world``."""
        if self.passenger_window is not None:
            return self.passenger_window
        return self.slots(world) if self.slots_per_taxi is not None else world.num_passengers

    def slots(self, world: WorldConfig) -> int:
        """Without a window: the passenger rows this spec reads in ``world`` (``slots_per_taxi`` x its taxis, up)."""
        per_taxi = world.num_passengers / world.num_taxis if self.slots_per_taxi is None else self.slots_per_taxi
        return math.ceil(round(per_taxi * world.num_taxis, 6))  # round: 7 / 3 * 3 must stay 7

    def layout(self, world: WorldConfig) -> Layout:
        """The fields this spec observes in ``world``, as :func:`observation_layout` gives them."""
        return self._layout_of(world, self.rows(world))

    def computed_layout(self, world: WorldConfig) -> Layout:
        """The layout the observer computes before the passenger window picks each taxi's rows: :meth:`layout`
        with a row for every passenger of the world's state; the same as it without a window."""
        return self._layout_of(world, world.num_passengers)

    def _layout_of(self, world: WorldConfig, rows: int) -> Layout:
        stops, lookahead = self.stops, self.lookahead
        return _layout(rows, self.history_len, self.patch_size, max(world.num_taxis - 1, 1),
                       stops is not None, stops is not None and (stops.rivals or stops.claims),
                       stops is not None and stops.claims, lookahead is not None)  # fmt: skip

    def reads(self, world: WorldConfig) -> str | None:
        """None when this spec can observe ``world``, else the one line that says which part of it it cannot read
        and the fix. The world is never changed."""
        if self.passenger_window is None and self.slots_per_taxi is not None and self.slots(world) > MAX_PASSENGERS:
            per_taxi = self.slots_per_taxi
            most = max(n for n in range(1, MAX_TAXIS + 1) if math.ceil(round(per_taxi * n, 6)) <= MAX_PASSENGERS)
            return (
                f"the world has {world.num_taxis} taxis and this policy reads {per_taxi:g} passenger rows per taxi, so "
                f"fleets of 1 to {most} taxi(s) fit the passenger axis of at most {MAX_PASSENGERS} rows: fly a larger "
                "fleet with a passenger window (e.g. 24)"
            )
        if self.passenger_window is None and world.num_passengers > self.slots(world):
            return (
                f"the world has {world.num_passengers} passenger rows; this policy reads {self.slots(world)}: give "
                f"it at most {self.slots(world)} requests, or fly it with a passenger window"
            )
        if self.fleet_rows is not None and world.num_taxis - 1 != self.fleet_rows:
            return (
                f"this policy reads the other taxis by position ({self.fleet_rows} rows), but the world has "
                f"{world.num_taxis} taxis: fly it with {self.fleet_rows + 1} taxis"
            )
        if self.passenger_window is not None and self.passenger_window < world.seats:
            try:
                check_integer("passenger_window", self.passenger_window, world.seats, MAX_PASSENGERS,
                              fix=passenger_window_fix(world.seats))  # fmt: skip
            except ConfigError as err:
                return str(err)
        if self.hover and not world.hover_action:
            return (
                "this policy waits with the hover action (16), which this world refuses: build it with "
                "hover_action=True"
            )
        return None

    def to_dict(self) -> dict[str, Any]:
        """Plain values (ints, floats, bools, None, dicts of them): ``torch.load(weights_only=True)`` and JSON read
        them."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ObserverSpec:
        """The inverse of :meth:`to_dict`; :class:`ConfigError` naming the key for an unknown one."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"observer spec keys {unknown} are unknown; the keys are {sorted(known)}.")
        values = dict(data)
        for name, part in (("stops", StopsSpec), ("lookahead", LookaheadSpec)):
            value = values.get(name)
            if isinstance(value, Mapping):
                try:
                    values[name] = part(**value)
                except TypeError:
                    fields = [f.name for f in dataclasses.fields(part)]
                    raise ConfigError(f"observer spec {name}={dict(value)!r}: its keys are {fields}.") from None
        return cls(**values)


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
    "LookaheadSpec",
    "ObserverSpec",
    "StopsSpec",
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
