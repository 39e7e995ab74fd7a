"""Ray-traced maps (uamfleet.radio.raytrace, uamfleet-radio-map): the map's frame, free space against Friis, the
grid placement rule, provenance, and saved maps read back exactly.

The tests that ray-trace need Sionna RT (the extra ``rt``); they skip without it, unless UAMFLEET_REQUIRE_RT=1
(``bash scripts/rt.sh``, where it is installed: a skip there would let the CI step pass without testing). The
file format, the SINR combination and the command's input checks need no Sionna and always run.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from uamfleet.cli import radio_map as radio_map_cli
from uamfleet.presets import make_config
from uamfleet.radio import BaseStation, RadioMap, load_radio_map, read_radio_map_npz, save_radio_map_npz
from uamfleet.radio import raytrace
from uamfleet.radio.channel_3gpp import expected_sinr_map_3gpp
from uamfleet.radio.scene_check import UnsafeSceneError, check_scene

SPEED_OF_LIGHT = 299_792_458.0


def require_sionna() -> ModuleType:
    """``sionna.rt``; skipped when absent, unless UAMFLEET_REQUIRE_RT=1 (then it fails)."""
    if os.environ.get("UAMFLEET_REQUIRE_RT") == "1":
        return importlib.import_module("sionna.rt")
    return pytest.importorskip("sionna.rt")


def friis_gain_db(distance_m: np.ndarray, carrier_ghz: float) -> np.ndarray:
    """Free-space path gain of isotropic antennas, ``20 log10(lambda / (4 pi d))``."""
    wavelength = SPEED_OF_LIGHT / (carrier_ghz * 1e9)
    return 20.0 * np.log10(wavelength / (4.0 * math.pi * distance_m))


# -- no Sionna needed -------------------------------------------------------------------------------------------


def test_best_server_sinr_by_hand() -> None:
    # Three cells, two GBS, noise 0.5 mW. Cell 0: 1 vs 0.5 -> 1 / (0.5 + 0.5) = 0 dB. Cell 1: only GBS 1 at 2 mW
    # -> 2 / 0.5 = 6.02 dB. Cell 2: no ray arrived from either -> NaN (not computed).
    received = np.array([[1.0, 0.0, 0.0], [0.5, 2.0, 0.0]])
    sinr = raytrace.best_server_sinr_db(received, np.array([1.0, 1.0]), noise_mw=0.5)
    np.testing.assert_allclose(sinr[:2], [0.0, 10 * math.log10(4.0)], atol=1e-12)
    assert np.isnan(sinr[2])
    # Half-loaded interferers: cell 0's best is GBS 0 with 0.25 mW of interference: 1 / 0.75.
    half = raytrace.best_server_sinr_db(received[:, :1], np.array([0.5, 0.5]), noise_mw=0.5)
    np.testing.assert_allclose(half, [10 * math.log10(1 / 0.75)], atol=1e-12)


def small_map() -> RadioMap:
    stations = (
        BaseStation(x_m=120.0, y_m=80.0, height_m=20.0, name="GBS 0"),
        BaseStation(x_m=300.0, y_m=210.0, height_m=25.0, power_dbm=43.0, loading=0.5, name="GBS 1"),
    )
    radio = expected_sinr_map_3gpp(stations, side_m=400.0, resolution_m=10.0, name="small")
    nan_cell = radio.sinr_db.copy()
    nan_cell[3, 4] = np.nan  # a not-computed cell survives the round trip
    return RadioMap(
        sinr_db=nan_cell, resolution_m=10.0, origin_m=(-5.0, 2.5), side_m=390.0, name="small", altitude_m=100.0,
        base_stations=stations, source="test map",
    )  # fmt: skip


def test_npz_round_trip_is_exact(tmp_path: Path) -> None:
    radio = small_map()
    path = save_radio_map_npz(radio, tmp_path / "small.npz")
    back = read_radio_map_npz(path)
    np.testing.assert_array_equal(back.sinr_db, radio.sinr_db)  # NaN in the same cell, every value bit-equal
    for field in ("resolution_m", "origin_m", "side_m", "name", "altitude_m", "base_stations", "source"):
        assert getattr(back, field) == getattr(radio, field), field
    assert not back.is_estimate
    assert not list(tmp_path.glob(".*.tmp"))  # written atomically: no temp file left behind


def test_load_radio_map_and_scenarios_take_an_npz(tmp_path: Path) -> None:
    path = save_radio_map_npz(small_map(), tmp_path / "small.npz")
    radio = load_radio_map(path)
    assert radio.name == "small" and radio.shape == small_map().shape
    config = make_config("berlin_random", radio=str(path), num_taxis=1, step_m=50.0)
    assert config.radio.source == "test map"


def test_a_foreign_npz_is_refused(tmp_path: Path) -> None:
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match=r"other\.npz.*not a uamfleet radio map.*uamfleet-radio-map"):
        read_radio_map_npz(tmp_path / "other.npz")
    (tmp_path / "broken.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=r"cannot read radio map .*broken\.npz"):
        load_radio_map(tmp_path / "broken.npz")
    with pytest.raises(ValueError, match=r"must end in \.npz"):
        save_radio_map_npz(small_map(), tmp_path / "small.txt")


def exit_status(argv: list[str]) -> int:
    """The command's exit status: returned, or raised as SystemExit by a parse error (an unknown choice)."""
    try:
        return radio_map_cli.cli(argv)
    except SystemExit as done:
        return int(done.code or 0)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--out", "map.txt"], "written as .npz"),
        (["--gbs-m", "1", "2", "3", "4"], "X Y HEIGHT triples; got 4 numbers"),
        (["--threads", "0"], "--threads 0"),
        (["--samples-per-tx", "0"], "samples_per_tx must be an integer >= 1"),
        (["--antenna-pattern", "yagi"], "yagi"),
    ],
)
def test_command_refuses_bad_input_in_one_line(
    argv: list[str], message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    assert exit_status(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not list(tmp_path.iterdir())


def test_help_describes_the_command_and_prints_each_default_once(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    assert exit_status(["--help"]) == 0
    out = capsys.readouterr().out
    assert "Ray-trace the SINR map of a city with Sionna RT" in out and "--gbs-spacing-m" in out
    assert "(default: the scene's bounding box)" in out
    for line in out.splitlines():
        assert line.count("(default:") <= 1, line


def test_command_refuses_to_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "munich.npz"
    out.write_bytes(b"earlier map")
    assert exit_status(["--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert out.read_bytes() == b"earlier map"


# -- ray tracing (Sionna RT) ---------------------------------------------------------------------------------


FREE_SPACE_EXTENT = (-40.0, 30.0, 360.0, 530.0)  # scene metres: 40 x 50 cells of 10 m, not square
FREE_SPACE_GBS = BaseStation(x_m=137.0, y_m=262.0, height_m=20.0, name="GBS 0")  # in the map's frame


@pytest.fixture(scope="module")
def free_space_map() -> RadioMap:
    require_sionna()
    return raytrace.ray_traced_radio_map(
        "empty", altitude_m=100.0, cell_m=10.0, base_stations=[FREE_SPACE_GBS], extent=FREE_SPACE_EXTENT,
        params=raytrace.RayTracingParams(samples_per_tx=10**7),
    )  # fmt: skip


def test_frame_a_transmitter_appears_in_its_cell(free_space_map: RadioMap) -> None:
    radio = free_space_map
    assert radio.shape == (40, 50)  # 400 m east x 500 m north: x first
    assert radio.origin_m == (0.0, 0.0) and radio.resolution_m == 10.0
    # World (0, 0) is the first cell's centre, the scene point (-40 + 5, 30 + 5).
    assert raytrace.provenance(radio)["scene_origin_m"] == [-35.0, 35.0]
    # The GBS at (137, 262) is in cell (round(13.7), round(26.2)) = (14, 26): the strongest cell (straight below
    # it the UAV is nearest).
    assert np.unravel_index(np.nanargmax(radio.sinr_db), radio.shape) == (14, 26)
    assert radio.base_stations == (FREE_SPACE_GBS,)


def path_gain_error_db(radio: RadioMap, image_height_m: float | None) -> np.ndarray:
    """Ray-traced path gain minus the formula's at every cell: Friis from the GBS (20 m) to the cell centre at
    100 m, plus, with ``image_height_m``, the ray reflected by a perfect conductor, whose path is as long as
    the line from the GBS's image (-20 m) to the cell. The radio map adds path powers, not fields, so the
    two-ray gain is the sum of both rays' Friis gains (|R| = 1), without interference fringes.
    One GBS, no interferer: SINR = P G / N, so the path gain is SINR + N - P."""
    gain_db = radio.sinr_db + raytrace.RayTracingParams().noise_dbm - FREE_SPACE_GBS.power_dbm
    x = np.arange(radio.shape[0])[:, None] * 10.0
    y = np.arange(radio.shape[1])[None, :] * 10.0
    ground_m2 = (x - FREE_SPACE_GBS.x_m) ** 2 + (y - FREE_SPACE_GBS.y_m) ** 2
    expected_mw = 10 ** (friis_gain_db(np.sqrt(ground_m2 + (100.0 - 20.0) ** 2), 2.0) / 10)
    if image_height_m is not None:
        expected_mw = expected_mw + 10 ** (friis_gain_db(np.sqrt(ground_m2 + (100.0 + image_height_m) ** 2), 2.0) / 10)
    return np.asarray(gain_db - 10 * np.log10(expected_mw))


def test_free_space_matches_friis_within_half_a_db(free_space_map: RadioMap) -> None:
    error_db = path_gain_error_db(free_space_map, image_height_m=None)
    assert not np.isnan(error_db).any()
    assert np.abs(error_db).max() < 0.5
    assert abs(error_db.mean()) < 0.05  # no bias: the spread is Monte-Carlo noise


GROUND_PLANE_XML = """<scene version="2.1.0">
  <bsdf type="itu-radio-material" id="metal">
    <string name="type" value="metal"/>
    <float name="thickness" value="0.1"/>
  </bsdf>
  <shape type="rectangle" id="ground">
    <transform name="to_world"><scale x="2000" y="2000"/></transform>
    <ref id="metal" name="bsdf"/>
  </shape>
</scene>
"""


def test_metal_ground_plane_matches_two_rays_within_half_a_db(tmp_path: Path) -> None:
    require_sionna()
    scene = tmp_path / "ground.xml"  # a 4 km x 4 km metal plane at z = 0, centred on the scene origin
    scene.write_text(GROUND_PLANE_XML, encoding="utf-8")
    radio = raytrace.ray_traced_radio_map(
        scene, base_stations=[FREE_SPACE_GBS], extent=FREE_SPACE_EXTENT,
        params=raytrace.RayTracingParams(samples_per_tx=10**7),
    )  # fmt: skip
    assert radio.name == "ground"
    error_db = path_gain_error_db(radio, image_height_m=20.0)
    assert not np.isnan(error_db).any()
    assert np.abs(error_db).max() < 0.5
    # The reflection is there: free space alone is 10 log10(1 + (r² + 80²) / (r² + 120²)) = 1.6 ... 3 dB lower.
    assert path_gain_error_db(radio, image_height_m=None).min() > 1.2


def test_provenance(free_space_map: RadioMap) -> None:
    record = raytrace.provenance(free_space_map)
    assert record["scene"] == "empty"
    assert record["sionna_rt_version"] == importlib.metadata.version("sionna-rt")
    assert record["seed"] == 42 and record["params"]["samples_per_tx"] == 10**7
    assert record["params"]["carrier_ghz"] == 2.0 and record["noise_dbm"] == pytest.approx(-95.0, abs=0.01)
    assert record["extent_m"] == list(FREE_SPACE_EXTENT) and record["gbs_placement"] == "given"
    assert record["altitude_m"] == 100.0 and record["cell_m"] == 10.0
    assert "RAY-TRACED: Sionna RT" in free_space_map.source
    with pytest.raises(ValueError, match="no ray-tracing provenance"):
        raytrace.provenance(small_map())


def test_grid_placement_rule() -> None:
    require_sionna()
    scene = raytrace.load_scene("empty")
    grid = raytrace.MapGrid.covering(raytrace.Extent(0.0, 0.0, 1500.0, 1000.0), 10.0)
    stations = raytrace.grid_base_stations(scene, grid, raytrace.RayTracingParams())
    # round(1500 / 750) = 2 columns, round(1000 / 750) = 1 row; sites at the grid cells' centres (scene 375 / 1125,
    # 500), i.e. 5 m less in the map's frame; no roof in free space: 20 m.
    assert [(bs.x_m, bs.y_m, bs.height_m) for bs in stations] == [(370.0, 495.0, 20.0), (1120.0, 495.0, 20.0)]


def test_unknown_scene_and_empty_scene_without_extent() -> None:
    require_sionna()
    with pytest.raises(ValueError, match=r"'gotham'.*munich"):
        raytrace.load_scene("gotham")
    with pytest.raises(FileNotFoundError, match=r"nowhere\.xml"):
        raytrace.load_scene("nowhere.xml")
    with pytest.raises(ValueError, match="pass extent"):
        raytrace.ray_traced_radio_map("empty", base_stations=[FREE_SPACE_GBS])


def test_command_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    require_sionna()
    out = tmp_path / "canyon.npz"
    argv = ["--scene", "simple_street_canyon", "--out", str(out), "--cell-m", "5", "--altitude-m", "60",
            "--gbs-m", "90", "60", "52", "--samples-per-tx", "100000", "--seed", "7"]  # fmt: skip
    assert radio_map_cli.cli(argv) == 0
    assert "wrote" in capsys.readouterr().out
    assert out.with_suffix(".png").stat().st_size > 10_000
    radio = load_radio_map(out)
    record = json.loads(radio.source.partition(" provenance: ")[2])
    assert record["scene"] == "simple_street_canyon" and record["seed"] == 7
    assert record["altitude_m"] == 60.0 and radio.resolution_m == 5.0
    assert radio.base_stations[0].x_m == 90.0 and radio.base_stations[0].height_m == 52.0
    assert np.isfinite(radio.sinr_db).mean() > 0.9  # above the roofs (51 m) the GBS reaches nearly every cell


# -- scenes are data, never code (uamfleet/radio/scene_check.py; tests/radio/test_scene_check.py without Sionna) -----


def test_every_built_in_scene_passes_the_scene_check() -> None:
    rt = require_sionna()
    folder = Path(rt.scene.__file__).parent / "scenes"
    scenes = sorted(folder.glob("*/*.xml"))
    assert len(scenes) >= 10  # munich, etoile, florence, san_francisco, simple_street_canyon, ...
    for path in scenes:
        checked = check_scene(path)  # the allowlist holds everything Sionna's own scenes use
        assert checked.shapes >= 1 and checked.files[0] == path.resolve(), path


def evil_scene(folder: Path, marker: Path) -> Path:
    """``folder/scene.xml`` whose shape type climbs from ``plugins/`` to ``meshes/evil.so``, a library whose
    constructor writes ``marker``; skipped where no C compiler is found."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler (cc) to build the library a crafted scene points at")
    (folder / "meshes").mkdir(parents=True)
    (folder / "plugins").mkdir()  # Mitsuba looks for plugins/<type>.so in each folder of its search path
    source = folder / "evil.c"
    source.write_text(
        "#include <stdio.h>\n__attribute__((constructor)) static void mark(void) {\n"
        f'  FILE *f = fopen("{marker}", "w"); if (f) {{ fputs("ran", f); fclose(f); }}\n}}\n'
    )
    subprocess.run([compiler, "-shared", "-fPIC", "-o", str(folder / "meshes" / "evil.so"), str(source)], check=True)
    scene = folder / "scene.xml"
    scene.write_text('<scene version="2.1.0">\n  <shape type="../meshes/evil"/>\n</scene>\n')
    return scene


def test_a_scene_pointing_at_a_library_runs_nothing(tmp_path: Path) -> None:
    require_sionna()
    marker = tmp_path / "marker"
    scene = evil_scene(tmp_path / "city", marker)
    # The scene is armed: Sionna's own loader, in another process, runs the library's constructor.
    loader = f"import sionna.rt as rt\ntry:\n    rt.load_scene({str(scene)!r})\nexcept Exception:\n    pass\n"
    subprocess.run([sys.executable, "-c", loader], check=True, capture_output=True, timeout=600)
    assert marker.read_text() == "ran"
    marker.unlink()
    with pytest.raises(UnsafeSceneError, match=r"line 2: <shape> type '\.\./meshes/evil' is a path"):
        raytrace.load_scene(scene)
    with pytest.raises(UnsafeSceneError, match="is a path"):
        raytrace.ray_traced_radio_map(scene, base_stations=[FREE_SPACE_GBS], extent=FREE_SPACE_EXTENT)
    assert not marker.exists()


CHECKED_PLY = """ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 2
property list uchar int vertex_indices
end_header
-50 -50 0
50 -50 0
50 50 0
-50 50 0
3 0 1 2
3 0 2 3
"""


def test_a_checked_scene_with_a_mesh_and_an_include_loads_and_traces(tmp_path: Path) -> None:
    require_sionna()
    folder = tmp_path / "city"
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "ground.ply").write_text(CHECKED_PLY)  # a 100 m square at z = 0, centred on the origin
    (folder / "parts").mkdir()
    (folder / "parts" / "roof.xml").write_text(
        '<scene version="2.1.0">\n  <shape type="rectangle" id="roof">\n'
        '    <transform name="to_world"><scale value="$half"/><translate x="100" z="$height"/></transform>\n'
        '    <ref id="metal" name="bsdf"/>\n  </shape>\n</scene>\n'
    )  # a 40 m square 30 m up, centred at x = 100
    scene = folder / "scene.xml"
    scene.write_text(
        '<scene version="2.1.0">\n  <default name="half" value="20"/>\n  <default name="height" value="30"/>\n'
        '  <bsdf type="itu-radio-material" id="metal">\n    <string name="type" value="metal"/>\n'
        '    <float name="thickness" value="0.1"/>\n  </bsdf>\n'
        '  <shape type="ply" id="ground">\n    <string name="filename" value="meshes/ground.ply"/>\n'
        '    <ref id="metal" name="bsdf"/>\n  </shape>\n  <include filename="parts/roof.xml"/>\n</scene>\n'
    )
    loaded = raytrace.load_scene(scene)
    box = loaded.mi_scene.bbox()
    np.testing.assert_allclose([list(box.min), list(box.max)], [[-50, -50, 0], [120, 50, 30]], atol=1e-4)
    radio = raytrace.ray_traced_radio_map(
        scene, cell_m=10.0, base_stations=[BaseStation(x_m=30.0, y_m=50.0, height_m=20.0)],
        params=raytrace.RayTracingParams(samples_per_tx=10**5),
    )  # fmt: skip
    assert radio.shape == (17, 10)  # the default area: the bounding box, 170 m x 100 m
    assert np.isfinite(radio.sinr_db).mean() > 0.9


def test_a_checked_scene_sionna_cannot_load_fails_in_one_line(tmp_path: Path) -> None:
    require_sionna()
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "broken.ply").write_text(CHECKED_PLY.replace("-50 -50 0", "-50 x 0"))
    scene = tmp_path / "broken.xml"
    scene.write_text(
        '<scene version="2.1.0">\n  <shape type="ply" id="m">\n'
        '    <string name="filename" value="meshes/broken.ply"/>\n  </shape>\n</scene>\n'
    )
    pattern = r"broken\.xml' passed the scene check but Sionna could not load it: .*PLY"
    with pytest.raises(ValueError, match=pattern) as err:
        raytrace.load_scene(scene)
    assert "\n" not in str(err.value)
