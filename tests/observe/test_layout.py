"""The observation spec (:mod:`uamfleet.observe.spec`) is the one owner of the observation: the observer's output, its
space, the normaliser, the policy and both documents (``docs/rules.md``, the ``parallel_env`` docstring) agree
with it, for every combination of the stop flags and several fleet sizes."""

from __future__ import annotations

import inspect
import itertools
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import small_config

from uamfleet.config import ConfigError, EnvConfig, Request
from uamfleet.observe import spec as layout_module
from uamfleet.observe.spec import (
    ALL_FIELDS,
    FIELD_KIND,
    FieldSpec,
    field_kind,
    layout_differences,
    layout_from_dict,
    layout_to_dict,
    observation_layout,
    observation_space,
)
from uamfleet.env.parallel_env import UAMFleetParallelEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.types import PASSENGER_FEATURES, STATE_TAXI_FEATURES, STOP_PATH_CLIP

RULES = Path(__file__).resolve().parents[2] / "docs" / "rules.md"
OPEN_7 = "\n".join(["......."] * 7)
STOP_FLAGS = [  # (stop_features, stop_rivals, stop_claims[, heading_lookahead]): every valid combination
    (False, False, False), (True, False, False), (True, True, False), (True, False, True), (True, True, True),
    (True, False, False, True), (True, True, True, True),
]  # fmt: skip


def fleet_config(num_taxis: int, flags: tuple[bool, ...], **overrides: object) -> EnvConfig:
    stops, rivals, claims, *lookahead = flags
    reqs = (
        Request(0, (250.0, 250.0), (550.0, 450.0)),
        Request(0, (450.0, 150.0), (150.0, 550.0)),
        Request(3, (650.0, 650.0), (50.0, 50.0)),
    )
    return small_config(
        OPEN_7, starts_m=None, num_taxis=num_taxis, requests=reqs, seats=1, stop_features=stops,
        stop_rivals=rivals, stop_claims=claims, heading_lookahead=bool(lookahead and lookahead[0]), **overrides,
    )  # fmt: skip


# ---- the observer's output is the spec --------------------------------------------------------------------


@pytest.mark.parametrize(("num_taxis", "flags"), list(itertools.product([1, 2, 3, 5], STOP_FLAGS)))
def test_observations_have_the_spec_fields_shapes_dtypes_and_bounds(num_taxis: int, flags: tuple) -> None:
    cfg = fleet_config(num_taxis, flags, max_passengers=4, history_len=2, patch_size=3)
    layout = observation_layout(cfg)
    env = VectorEnv(cfg, num_envs=2)
    assert env.single_observation_space == observation_space(layout)
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=1)
    for step in range(12):
        assert list(obs) == list(layout), "the observer returns the spec's fields in its order"
        for name, spec in layout.items():
            value = obs[name]
            assert value.shape == (2, num_taxis, *spec.shape), name
            assert value.dtype == np.dtype(spec.dtype), name
            assert np.all((value >= spec.low) & (value <= spec.high)), f"{name} leaves [{spec.low}, {spec.high}]"
            if spec.columns is not None:
                assert len(spec.columns) == spec.shape[-1], name
            if spec.kind == "mask":
                assert set(np.unique(value)) <= {0, 1}, name
        actions = np.where(obs["action_mask"] > 0, rng.random(obs["action_mask"].shape), -1).argmax(-1)
        obs, *_ = env.step(actions)
        del step


def test_which_fields_exist_depends_on_flags_never_on_the_fleet_size() -> None:
    for flags in STOP_FLAGS:
        fields = {n: list(observation_layout(fleet_config(n, flags))) for n in (1, 2, 4, 9)}
        assert len({tuple(f) for f in fields.values()}) == 1, (flags, fields)
    stops_only = observation_layout(fleet_config(4, (True, False, False)))
    assert "stop_rivals" not in stops_only  # a fleet observes rivals only when asked
    lone = VectorEnv(fleet_config(1, (True, True, False)), num_envs=1)
    obs, _ = lone.reset(seed=0)
    waiting = obs["passengers"][0, 0, :, PASSENGER_FEATURES.index("waiting")] > 0
    assert waiting.any()
    rivals = obs["stop_rivals"][0, 0]  # a lone taxi has no rival: the clip distance, nobody nearer
    assert np.all(rivals[waiting, 0] == STOP_PATH_CLIP) and np.all(rivals[:, 1] == 0.0)
    with pytest.raises(ConfigError, match="stop_rivals=True needs stop_features=True"):
        fleet_config(2, (False, True, False))


def test_the_layout_builds_no_world(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("observation_layout built a World")

    monkeypatch.setattr("uamfleet.sim.world.World.__init__", refuse)
    assert set(observation_layout(fleet_config(3, (True, True, True, True)))) == set(ALL_FIELDS)


def test_shipped_fleet_policy_resizes_without_building_an_env(monkeypatch: pytest.MonkeyPatch) -> None:
    import uamfleet
    from uamfleet.instances import make_fleet_instance

    two = make_fleet_instance("berlin", 3, num_taxis=2, num_requests=4).world

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("built a VectorEnv to learn shapes")

    monkeypatch.setattr("uamfleet.env.vector_env.VectorEnv.__init__", refuse)
    policy = uamfleet.pretrained("berlin_fleet_v1")
    policy.fit(two)  # 6 requests per taxi: 12 rows for 2 taxis
    shapes = policy.fitted()[2]
    assert shapes is not None and shapes["others"] == (1, 3) and shapes["stop_claims"] == (12, 2)
    windowed = uamfleet.pretrained("berlin_fleet")
    windowed.fit(two)  # its 24-row window, whatever the fleet size
    shapes = windowed.fitted()[2]
    assert shapes is not None and shapes["others"] == (1, 3) and shapes["stop_claims"] == (24, 2)


# ---- kinds, and the normaliser that reads them ---------------------------------------------------------------


def test_kinds_are_consistent_with_dtypes_and_row_masks() -> None:
    full = observation_layout(fleet_config(3, (True, True, True, True)))
    assert tuple(full) == ALL_FIELDS and FIELD_KIND == {n: s.kind for n, s in full.items()}
    for name, spec in full.items():
        if spec.kind == "mask":
            assert (spec.dtype, spec.low, spec.high) == ("int8", 0, 1), name
        if spec.kind in ("feature", "set"):
            assert spec.dtype == "float32", name
        if spec.kind == "set":
            mask = full[spec.row_mask or ""]
            assert mask.kind == "mask" and mask.shape == spec.shape[:1], name
        else:
            assert spec.row_mask is None, name
    with pytest.raises(ValueError, match="'speed' is not an observation field"):
        field_kind("speed")


def test_the_normaliser_scales_features_and_sets_only_and_keeps_masked_rows_zero() -> None:
    full = observation_layout(fleet_config(3, (True, True, True), max_passengers=4))
    norm = ObservationNormalizer({n: s.shape for n, s in full.items()})
    assert set(norm.fields) == {n for n, s in full.items() if s.kind in ("feature", "set")}
    rng = np.random.default_rng(0)
    obs = {n: (rng.random((5, *s.shape)) * 3 + 1).astype(s.dtype) for n, s in full.items()}
    obs["passenger_mask"][:] = [1, 0, 1, 0]
    obs["others_mask"][:] = [0, 1]
    norm.update(obs)
    out = norm(obs)
    for name, spec in full.items():
        if spec.kind in ("mask", "raw"):
            assert out[name] is obs[name], name
        else:
            kept = out[name] if spec.row_mask is None else out[name][:, obs[spec.row_mask][0] > 0]
            assert np.allclose(kept.mean(0), 0.0, atol=1e-3), name  # each element scaled by this batch's moments
    assert np.all(out["passengers"][:, [1, 3]] == 0.0) and np.all(out["others"][:, 0] == 0.0)
    assert np.all(out["stop_rivals"] == obs["stop_rivals"])  # raw: untouched


# ---- serialised and compared -----------------------------------------------------------------------------


def test_a_layout_survives_a_round_trip_through_plain_data() -> None:
    full = observation_layout(fleet_config(2, (True, True, True)))
    data = layout_to_dict(full)
    assert re.fullmatch(r"[\[\]{}a-z0-9_.,:\"' -]*", repr(data).lower()), "plain lists, strings and numbers only"
    assert layout_from_dict(data) == full
    with pytest.raises(ValueError, match="observation field 'self'"):
        layout_from_dict({"self": {"shape": [4]}})
    with pytest.raises(ValueError, match="kind 'scaled'"):
        layout_from_dict({"self": {**data["self"], "kind": "scaled"}})


def test_layout_differences_name_each_field_and_attribute() -> None:
    small = observation_layout(fleet_config(2, (True, False, False), max_passengers=4))
    large = observation_layout(fleet_config(2, (True, False, True), max_passengers=5))
    diffs = layout_differences(small, large)
    assert any(line.startswith("'passengers': shape (4, 12) vs (5, 12)") for line in diffs)
    assert "'stop_claims': only in the second layout" in diffs
    assert not any(line.startswith("'self'") for line in diffs)
    assert layout_differences(small, small) == []


# ---- the documents agree with the spec ------------------------------------------------------------------

SIZES = {"P": 5, "H": 4, "k": 6, "A": 3}  # distinct, so a shape written with the wrong symbol shows


def doc_shape(text: str) -> tuple[int, ...]:
    """A documented shape such as ``(max(A−1, 1), 3)`` at :data:`SIZES`."""
    expr = text.replace("−", "-").strip()
    assert re.fullmatch(r"[()PHkA0-9, +\-max]*", expr), f"unexpected shape {text!r}"
    return tuple(eval(expr, {"__builtins__": {}, "max": max}, dict(SIZES)))  # the characters are checked above


def rules_rows() -> dict[str, tuple[str, str, str]]:
    """{field: (shape, dtype, meaning)} of the field tables of docs/rules.md's "Observation" section."""
    text = RULES.read_text()
    section = text[text.index("## Observation") : text.index("## State")]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 5 and re.fullmatch(r"`\w+`", cells[0]):
            rows[cells[0].strip("`")] = (cells[1], cells[2], cells[4])
    return rows


def docstring_rows() -> dict[str, tuple[str, str, str]]:
    """{field: (shape, dtype, meaning)} of the observation table in UAMFleetParallelEnv's docstring (an RST simple
    table; a row with an empty first column continues the one above)."""
    lines = inspect.cleandoc(UAMFleetParallelEnv.__doc__ or "").splitlines()
    borders = [i for i, line in enumerate(lines) if re.fullmatch(r"=+( +=+)+", line)]
    assert lines[borders[0] + 1].split()[:2] == ["field", "shape"]
    spans = [m.span() for m in re.finditer(r"=+", lines[borders[0]])]
    rows: dict[str, list[str]] = {}
    name = ""
    for line in lines[borders[1] + 1 : borders[2]]:
        cells = [line[a:b].strip() if i < len(spans) - 1 else line[a:].strip() for i, (a, b) in enumerate(spans)]
        if cells[0]:
            name = cells[0].strip("`")
            rows[name] = [cells[1], cells[2], cells[4]]
        else:
            rows[name][2] += " " + cells[4]
    return {k: (v[0], v[1], v[2]) for k, v in rows.items()}


@pytest.mark.parametrize("document", ["docs/rules.md", "parallel_env docstring"])
def test_the_documented_fields_shapes_dtypes_and_columns_are_the_specs(document: str) -> None:
    rows = rules_rows() if document == "docs/rules.md" else docstring_rows()
    cfg = fleet_config(SIZES["A"], (True, True, True, True), max_passengers=SIZES["P"], history_len=SIZES["H"],
                       patch_size=SIZES["k"])  # fmt: skip
    spec = observation_layout(cfg)
    assert list(rows) == list(spec), f"{document} lists {list(rows)}; the spec has {list(spec)}"
    for name, (shape, dtype, meaning) in rows.items():
        assert doc_shape(shape) == spec[name].shape, f"{document}: {name} shape {shape}"
        assert dtype == spec[name].dtype, f"{document}: {name} dtype {dtype}"
        if spec[name].columns == PASSENGER_FEATURES:
            assert "PASSENGER_FEATURES" in meaning, name
            continue
        for column in spec[name].columns or ():
            quoted = f"`{column}`" if document == "docs/rules.md" else column
            assert quoted in meaning, f"{document}: the {name} row does not name its column {column!r}"
    for name in ("stop_paths", "stop_rivals"):
        assert f"≤ {STOP_PATH_CLIP:g}" in rows[name][2] or f"<= {STOP_PATH_CLIP:g}" in rows[name][2], name


def test_the_passenger_features_table_lists_the_columns_in_order() -> None:
    text = RULES.read_text()
    table = text[text.index("Passenger features (") : text.index("## State")]
    names = []
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and re.fullmatch(r"[\d, ]+", cells[0]):
            indices = [int(i) for i in cells[0].split(",")]
            found = re.findall(r"`(\w+)`", cells[1])
            assert [PASSENGER_FEATURES.index(n) for n in found] == indices, cells
            names += found
    assert tuple(names) == PASSENGER_FEATURES


def test_field_spec_space_is_the_box_of_its_bounds() -> None:
    spec = FieldSpec((2, 3), "float32", -1.0, 2.0, ("a", "b", "c"), "feature")
    box = spec.space()
    assert box.shape == (2, 3) and box.dtype == np.float32
    assert np.all(box.low == -1.0) and np.all(box.high == 2.0)
    assert layout_module.observation_space({"x": spec})["x"] == box


def test_the_kernels_write_each_column_where_the_spec_names_it() -> None:
    """Every column of ``self``, ``history``, ``others`` and the state's taxi rows, found by its name in the spec,
    holds its value computed here by hand (a kernel that writes a column by position fails after a reorder)."""
    cfg = fleet_config(3, (False, False, False), history_len=2)
    env = VectorEnv(cfg, num_envs=1)
    obs, _ = env.reset(seed=4)
    obs, *_ = env.step(np.argmax(obs["action_mask"], -1))
    s, side, spec = env.state, env.world.side_m, env.observer.layout
    pos, seats = s.pos_m[0], s.free_seats[0] / cfg.seats

    def column(field: str, name: str) -> np.ndarray:
        return obs[field][0][..., list(spec[field].columns or ()).index(name)]

    np.testing.assert_allclose(column("self", "x"), pos[:, 0] / side, rtol=1e-6)
    np.testing.assert_allclose(column("self", "y"), pos[:, 1] / side, rtol=1e-6)
    np.testing.assert_allclose(column("self", "free_seats"), seats)
    np.testing.assert_allclose(column("self", "time"), 1 / cfg.time_limit_steps)
    hist = (s.history_m[0] - pos[:, None]) / side  # [A, H, 2]
    np.testing.assert_allclose(column("history", "dx"), hist[..., 0], atol=1e-7)
    np.testing.assert_allclose(column("history", "dy"), hist[..., 1], atol=1e-7)
    np.testing.assert_allclose(column("history", "free_seats"), s.history_seats[0] / cfg.seats)
    for a in range(3):
        others = [b for b in range(3) if b != a]
        rel = (pos[others] - pos[a]) / side
        np.testing.assert_allclose(column("others", "dx")[a], rel[:, 0], atol=1e-7)
        np.testing.assert_allclose(column("others", "dy")[a], rel[:, 1], atol=1e-7)
        np.testing.assert_allclose(column("others", "free_seats")[a], seats[others])
    taxis = env.global_state()[0, : 3 * len(STATE_TAXI_FEATURES)].reshape(3, -1)
    np.testing.assert_allclose(taxis[:, STATE_TAXI_FEATURES.index("index")], np.arange(3) / 3, rtol=1e-6)
    np.testing.assert_allclose(taxis[:, STATE_TAXI_FEATURES.index("free_seats")], seats)
