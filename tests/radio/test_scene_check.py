"""Scenes are data, never code (uamfleet/radio/scene_check.py): crafted scenes are refused in one line before Sionna
(Mitsuba) is reached, and nothing outside the scene's folder is opened. Needs no Sionna: the loader is replaced by
one that fails the test if it is ever called (tests/radio/test_raytrace.py proves the same with Sionna present).
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from test_raytrace import CHECKED_PLY as PLY
from test_raytrace import exit_status

from uamfleet.checks import SIZE_LIMITS
from uamfleet.radio import BaseStation, raytrace
from uamfleet.radio.scene_check import (
    ELEMENTS_PER_SHAPE,
    MAX_INCLUDE_DEPTH,
    MAX_NESTING,
    PLUGIN_TYPES,
    UnsafeSceneError,
    check_scene,
)

SECRET = "root:x:0:0:SECRET-LINE-OF-AN-OUTSIDE-FILE"
_opened: list[str] | None = None


def _audit(event: str, args: tuple[Any, ...]) -> None:
    if event == "open" and _opened is not None and isinstance(args[0], (str, bytes, os.PathLike)):
        _opened.append(os.fsdecode(args[0]))


sys.addaudithook(_audit)  # cannot be removed; records only while a test's `opened` fixture is active


@pytest.fixture
def opened() -> Iterator[list[str]]:
    """Every path opened (Python's "open" audit event) while the test runs."""
    global _opened
    _opened = []
    try:
        yield _opened
    finally:
        _opened = None


@pytest.fixture(autouse=True)
def no_sionna(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Sionna's loader, replaced by one that records the XML it was given and fails the test unless it expects it."""
    loaded: list[str] = []

    class FakeRt:
        @staticmethod
        def load_scene_from_string(xml: str) -> Any:
            loaded.append(xml)
            raise LoaderReached(xml)

        @staticmethod
        def load_scene(*args: Any) -> Any:
            pytest.fail(f"Sionna's load_scene was called with {args}")

    monkeypatch.setattr(raytrace, "_sionna_rt", lambda: FakeRt)
    return loaded


class LoaderReached(Exception):
    """The checked scene reached Sionna's loader (the fake one)."""


@pytest.fixture
def city(tmp_path: Path) -> Path:
    """A scene folder ``city/`` with a mesh, beside an ``outside/`` folder holding a secret file."""
    folder = tmp_path / "city"
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "ground.ply").write_text(PLY, encoding="ascii")
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "secret.ply").write_text(SECRET + "\n", encoding="ascii")
    (tmp_path / "outside" / "secret.xml").write_text(f"<scene version='2.1.0'><!-- {SECRET} --></scene>")
    return folder


MATERIAL = """  <bsdf type="itu-radio-material" id="concrete">
    <string name="type" value="concrete"/>
    <float name="thickness" value="0.1"/>
  </bsdf>
"""


def scene_xml(body: str) -> str:
    return f'<scene version="2.1.0">\n{MATERIAL}{body}\n</scene>\n'


def write(folder: Path, body: str, name: str = "scene.xml") -> Path:
    path = folder / name
    path.write_text(scene_xml(body), encoding="utf-8")
    return path


def refused(path: Path, opened: list[str], *patterns: str) -> str:
    """The one-line message of loading ``path``; asserts that it names the patterns, that the loader was never
    reached and that nothing outside the scene's folder (but Python's own files) was opened."""
    with pytest.raises(UnsafeSceneError) as info:
        raytrace.load_scene(path)
    message = str(info.value)
    assert "\n" not in message and SECRET not in message and "SECRET" not in message
    assert repr(str(path.resolve())) in message or repr(str(path)) in message or "scene '" in message
    for pattern in patterns:
        assert pattern in message, (pattern, message)
    folder = path.resolve().parent
    outside = [p for p in opened if not Path(p).resolve().is_relative_to(folder)]
    assert not [p for p in outside if "outside" in p or p.startswith("/etc")], outside
    return message


# -- code: a plugin type is a name ---------------------------------------------------------------------------------


def evil_library(folder: Path, marker: Path) -> Path:
    """``folder/meshes/evil.so`` whose constructor writes ``marker`` (a plain file where no C compiler is found)."""
    library = folder / "meshes" / "evil.so"
    (folder / "plugins").mkdir(exist_ok=True)  # Mitsuba looks for plugins/<type>.so through its search path
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        library.write_bytes(b"\x7fELF not really")
        return library
    source = folder.parent / "evil.c"
    source.write_text(
        "#include <stdio.h>\n__attribute__((constructor)) static void mark(void) {\n"
        f'  FILE *f = fopen("{marker}", "w"); if (f) {{ fputs("ran", f); fclose(f); }}\n}}\n'
    )
    subprocess.run([compiler, "-shared", "-fPIC", "-o", str(library), str(source)], check=True)
    return library


@pytest.mark.parametrize("kind", ["climb", "absolute"])
def test_a_plugin_path_is_refused_and_nothing_runs(kind: str, city: Path, opened: list[str]) -> None:
    marker = city.parent / "marker"
    library = evil_library(city, marker)
    plugin = "../meshes/evil" if kind == "climb" else str(library.with_suffix(""))
    path = write(city, f'  <shape type="{plugin}"/>')
    message = refused(path, opened, "line 6", "<shape>", "is a path")
    assert plugin[:20] in message  # the type, shortened to one short line
    assert not marker.exists()
    assert str(library) not in opened


@pytest.mark.parametrize(
    ("body", "patterns"),
    [
        ('  <integrator type="evilplugin"/>', ("line 6", "<integrator>", "'evilplugin'", "allowed: path, direct")),
        ('  <shape type="serialized"/>', ("<shape>", "not one a city scene needs", "ply, obj, rectangle")),
        ('  <bsdf type="measured" id="m"/>', ("<bsdf>", "'measured'",)),
        ('  <path value="/"/>', ("line 6", "<path>", "not an element a scene may hold")),
        ('  <scene version="2.1.0"/>', ("line 6", "<scene>", "may only be the file's top element")),
        ('  <alias id="concrete" as="c"/>', ("<alias>", "not an element")),
        ('  <shape type="rectangle" evil="1"/>', ("<shape>", "attribute 'evil'")),
        ('  <shape type="$t"/>', ("<shape>", "$parameters may stand only in numbers")),
        ('  <shape type="ply"><string name="filename" value="$f"/></shape>', ("<string>", "only in numbers")),
        ('  <shape type="rectangle"><float name="x" value="$nope"/></shape>', ("<float>", "no <default> for it")),
        ('  <shape type="rectangle"><bsdf type="../../x" id="b"/></shape>', ("line 6", "<bsdf>", "is a path")),
        ('  <shape type="rectangle"><float name="a" value="1"><shape type="cube"/></float></shape>',
         ("<shape>", "cannot stand inside <float>")),
    ],
)  # fmt: skip
def test_elements_off_the_allowlist_are_refused(
    body: str, patterns: tuple[str, ...], city: Path, opened: list[str]
) -> None:
    refused(write(city, body), opened, *patterns)


# -- files: only inside the scene's folder ----------------------------------------------------------------------------


def ply_shape(filename: str) -> str:
    return f'  <shape type="ply" id="m">\n    <string name="filename" value="{filename}"/>\n  </shape>'


def test_a_mesh_outside_the_folder_is_refused_unread(city: Path, opened: list[str]) -> None:
    for name in ("../../etc/passwd", "../outside/secret.ply", "meshes/../../outside/secret.ply"):
        refused(write(city, ply_shape(name)), opened, "line 7", "<string>", "resolves outside the scene's folder")
    absolute = str(city.parent / "outside" / "secret.ply")
    refused(write(city, ply_shape(absolute)), opened, "line 7", "not absolute")
    refused(write(city, ply_shape("/etc/passwd")), opened, "not absolute")
    refused(write(city, ply_shape("meshes\\ground.ply")), opened, "relative path with '/'")


def test_a_symlink_inside_the_folder_pointing_outside_is_refused(city: Path, opened: list[str]) -> None:
    (city / "meshes" / "link.ply").symlink_to(city.parent / "outside" / "secret.ply")
    refused(write(city, ply_shape("meshes/link.ply")), opened, "resolves outside", "after symlinks")
    (city / "linked").symlink_to(city.parent / "outside")
    refused(write(city, ply_shape("linked/secret.ply")), opened, "resolves outside")


def test_a_missing_mesh_or_a_folder_is_refused(city: Path, opened: list[str]) -> None:
    # Mitsuba would look for a missing file in the current folder next: refused instead.
    refused(write(city, ply_shape("meshes/none.ply")), opened, "not a file inside the scene's folder")
    refused(write(city, ply_shape("meshes")), opened, "not a file inside the scene's folder")


def test_includes_of_system_or_outside_files_are_refused(city: Path, opened: list[str]) -> None:
    for name, reason in [
        ("/etc/passwd", "not absolute"),
        ("../outside/secret.xml", "resolves outside"),
        (str(city.parent / "outside" / "secret.xml"), "not absolute"),
    ]:
        refused(write(city, f'  <include filename="{name}"/>'), opened, "line 6", "<include>", reason)


def test_includes_are_checked_recursively_and_bounded(city: Path, opened: list[str]) -> None:
    (city / "parts").mkdir()
    (city / "parts" / "a.xml").write_text('<scene version="2.1.0">\n  <shape type="../plugins/evil"/>\n</scene>\n')
    message = refused(write(city, '  <include filename="parts/a.xml"/>'), opened, "line 2", "<shape>", "is a path")
    assert "a.xml" in message  # the line is the included file's
    (city / "loop.xml").write_text('<scene version="2.1.0"><include filename="loop.xml"/></scene>')
    refused(city / "loop.xml", opened, "<include>", "nests includes deeper than 8")


# -- the XML itself: no DTD, no entities ------------------------------------------------------------------------------

BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE lolz [
  <!ENTITY lol "lol">
  <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
  <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
  <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
  <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
  <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
  <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
  <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
  <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<scene version="2.1.0"><shape type="rectangle" id="&lol9;"/></scene>
"""


def test_billion_laughs_and_xxe_are_refused(city: Path, opened: list[str]) -> None:
    laughs = city / "laughs.xml"
    laughs.write_text(BILLION_LAUGHS)
    refused(laughs, opened, "line 2", "holds a DTD", "never read")
    xxe = city / "xxe.xml"
    secret = city.parent / "outside" / "secret.ply"
    xxe.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE scene [\n  <!ENTITY x SYSTEM "file://{secret}">\n]>\n'
        '<scene version="2.1.0"><shape type="rectangle" id="&x;"/></scene>\n'
    )
    refused(xxe, opened, "holds a DTD")
    xxe.write_text(xxe.read_text().replace(f"file://{secret}", "file:///etc/passwd"))
    refused(xxe, opened, "holds a DTD")


def test_malformed_xml_is_one_line(city: Path, opened: list[str]) -> None:
    (city / "bad.xml").write_text('<scene version="2.1.0">\n<shape type="rectangle">\n</scene>\n')
    refused(city / "bad.xml", opened, "not well-formed XML", "line 3")
    (city / "other.xml").write_text('<shape type="rectangle"/>\n')
    refused(city / "other.xml", opened, "top element is <scene>")


# -- sizes -------------------------------------------------------------------------------------------------------------


def plane(scale: str, translate: str = "") -> str:
    shift = f'<translate value="{translate}"/>' if translate else ""
    return (
        '  <shape type="rectangle" id="ground">\n'
        f'    <transform name="to_world"><scale value="{scale}"/>{shift}</transform>\n'
        '    <ref id="concrete" name="bsdf"/>\n  </shape>'
    )


def test_a_huge_plane_is_refused_before_loading(city: Path, opened: list[str]) -> None:
    # A rectangle is [-1, 1]^2: scaled by 1e7 it is 2e7 m wide, over the 50 km default.
    refused(write(city, plane("1e7")), opened, "line 6", "<shape>", "20,000,000 m wide", "UAMFLEET_MAX_SCENE_EXTENT_M")
    # A small plane moved far away makes the scene as wide (its box and the first plane's).
    body = plane("10") + "\n" + plane("10", "1e9 0 0").replace('id="ground"', 'id="far"')
    refused(write(city, body), opened, "line 10", "1,000,000,020 m wide")
    # A cube, a sphere and a cylinder are measured too; $parameters are resolved from <default>.
    cube = '<default name="s" value="3e4"/>\n  <shape type="cube"><transform name="to_world"><scale value="$s"/>'
    refused(write(city, cube + "</transform></shape>"), opened, "<shape>", "60,000 m wide")
    sphere = '<shape type="sphere"><float name="radius" value="4e4"/></shape>'
    refused(write(city, sphere), opened, "80,000 m wide")
    cylinder = '<shape type="cylinder"><point name="p1" x="0" y="0" z="1"/><float name="radius" value="3e4"/></shape>'
    refused(write(city, cylinder), opened, "60,001 m wide")  # radius 3e4 around the segment from z = 0 to 1
    rotated = '<shape type="rectangle"><transform name="to_world"><scale x="2e4" y="1"/>'
    write(city, rotated + '<rotate z="1" angle="90"/></transform></shape>')  # 40 km along y: within the limit
    assert check_scene(city / "scene.xml").shapes == 1


def test_the_extent_limit_is_overridable(city: Path, monkeypatch: pytest.MonkeyPatch, opened: list[str]) -> None:
    path = write(city, plane("1e3"))  # 2 km wide
    assert check_scene(path).shapes == 1
    monkeypatch.setenv("UAMFLEET_MAX_SCENE_EXTENT_M", "1000")
    refused(path, opened, "2,000 m wide", "over the limit of 1,000 m")


def test_too_many_shapes_are_refused(city: Path, monkeypatch: pytest.MonkeyPatch, opened: list[str]) -> None:
    monkeypatch.setenv("UAMFLEET_MAX_SCENE_SHAPES", "3")
    body = "\n".join(plane("10").replace('id="ground"', f'id="g{k}"') for k in range(3))
    assert check_scene(write(city, body)).shapes == 3
    body += "\n" + plane("10").replace('id="ground"', 'id="g3"')
    refused(write(city, body), opened, "4 shapes (plus included files)", "UAMFLEET_MAX_SCENE_SHAPES")
    # The XML elements in all are bounded too, 16 per allowed shape: 48 here. The scene, the material's 3 and a
    # rectangle with 44 properties make 49.
    floats = "".join(f'<float name="f{k}" value="1"/>' for k in range(44))
    refused(write(city, f'<shape type="rectangle">{floats}</shape>'), opened, "<float>", "is element 49, over 16 per")


def test_a_mesh_over_the_byte_limit_is_refused(city: Path, monkeypatch: pytest.MonkeyPatch, opened: list[str]) -> None:
    path = write(city, ply_shape("meshes/ground.ply"))
    xml_bytes, mesh_bytes = path.stat().st_size, len(PLY)
    assert check_scene(path).total_bytes == xml_bytes + mesh_bytes
    monkeypatch.setenv("UAMFLEET_MAX_SCENE_BYTES", str(xml_bytes + mesh_bytes - 1))
    refused(path, opened, f"needs {xml_bytes + mesh_bytes:,} bytes", "'ground.ply'", "UAMFLEET_MAX_SCENE_BYTES")
    monkeypatch.setenv("UAMFLEET_MAX_SCENE_BYTES", str(xml_bytes - 1))  # the XML alone: refused before parsing
    refused(path, opened, f"needs {xml_bytes:,} bytes")


def test_a_mesh_header_declaring_more_than_its_file_holds_is_refused(city: Path, opened: list[str]) -> None:
    # Mitsuba allocates what a PLY header declares: 2e9 vertices of 3 floats is 24 GB, from a file of a few bytes.
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    )
    (city / "meshes" / "bomb.ply").write_bytes(header.encode() + bytes(49))
    path = write(city, ply_shape("meshes/bomb.ply"))
    refused(path, opened, "line 7", "'bomb.ply'", "declares at least 24,000,000,001 bytes", "holds 50")
    # ascii: at least 2 bytes a value: 400 vertices x 3 floats and 2 faces x 1 list = 2,404 bytes, in a file of 53
    text = PLY.replace("element vertex 4", "element vertex 400")
    (city / "meshes" / "bomb.ply").write_text(text)
    refused(path, opened, "declares at least 2,404 bytes", "holds 53")
    (city / "meshes" / "bomb.ply").write_text("solid ascii stl\n")
    refused(path, opened, "which is no PLY file")
    (city / "meshes" / "bomb.dat").write_bytes(header.encode() + bytes(49))  # a ply shape reads any name as PLY
    refused(write(city, ply_shape("meshes/bomb.dat")), opened, "'bomb.dat'", "declares at least 24,000,000,001 bytes")
    assert check_scene(write(city, ply_shape("meshes/ground.ply"))).shapes == 1  # 4 vertices, 2 faces: fine


def test_deep_nesting_is_refused(city: Path, opened: list[str]) -> None:
    deep = '<bsdf type="twosided" id="a">' + '<bsdf type="twosided">' * 40 + "</bsdf>" * 41
    refused(write(city, deep), opened, "<bsdf>", "is nested 33 deep; elements nest at most 32")


# -- what passes, and what Sionna is then given ----------------------------------------------------------------------


def test_a_valid_scene_passes_and_sionna_gets_the_checked_xml(city: Path, no_sionna: list[str]) -> None:
    (city / "parts").mkdir()
    (city / "parts" / "roof.xml").write_text(
        '<scene version="2.1.0">\n  <shape type="ply" id="roof">\n'
        '    <string name="filename" value="meshes/ground.ply"/>\n'
        '    <transform name="to_world"><translate z="$h"/></transform>\n'
        '    <ref id="concrete" name="bsdf"/>\n  </shape>\n</scene>\n'
    )
    body = (
        '  <default name="h" value="12.5"/>\n'
        + ply_shape("meshes/ground.ply").replace('id="m"', 'id="ground"')
        + '\n  <include filename="parts/roof.xml"/>\n'
        + '  <bsdf type="twosided" id="mat-itu_glass"><bsdf type="diffuse">'
        + '<rgb name="reflectance" value="0.2 0.5 0.8"/></bsdf></bsdf>\n'
        + plane("100")
    )
    path = write(city, body)
    checked = check_scene(path)
    assert checked.shapes == 4  # two meshes, the include, the plane
    assert checked.files == (path.resolve(), (city / "parts" / "roof.xml").resolve(),
                             (city / "meshes" / "ground.ply").resolve())  # fmt: skip
    assert checked.total_bytes == sum(f.stat().st_size for f in checked.files)  # the mesh counted once
    with pytest.raises(LoaderReached):
        raytrace.load_scene(path)
    (xml,) = no_sionna
    assert xml == checked.xml
    mesh = str((city / "meshes" / "ground.ply").resolve())
    assert xml.count(f'value="{mesh}"') == 2  # absolute checked paths: Mitsuba's search path is never asked
    assert "<include" not in xml and "<default" not in xml and "$" not in xml
    assert '<translate z="12.5"' in xml and 'id="roof"' in xml


def test_a_scene_path_that_is_no_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nowhere\.xml' does not exist"):
        raytrace.load_scene(tmp_path / "nowhere.xml")
    (tmp_path / "dir.xml").mkdir()
    with pytest.raises(FileNotFoundError, match=r"dir\.xml' is a folder"):
        raytrace.load_scene(tmp_path / "dir.xml")


# -- the map's area and raster, before any loading ----------------------------------------------------------------

GBS = [BaseStation(x_m=10.0, y_m=10.0, height_m=20.0)]


def test_a_raster_over_the_cell_limit_is_refused_before_loading(city: Path) -> None:
    with pytest.raises(ValueError, match=r"a map of 1000 m x 1000 m on 0\.001 m cells needs 1,000,000,000,000 cells"):
        raytrace.ray_traced_radio_map("empty", cell_m=0.001, extent=(0, 0, 1000, 1000), base_stations=GBS)
    with pytest.raises(ValueError, match=r"cell_m=0 must be a positive number"):
        raytrace.ray_traced_radio_map("empty", cell_m=0, extent=(0, 0, 1000, 1000), base_stations=GBS)
    with pytest.raises(ValueError, match=r"the extent \(0, 0, 60000, 10\) is 60,000 m wide, over the limit of 50,000"):
        raytrace.ray_traced_radio_map("empty", extent=(0, 0, 60000, 10), base_stations=GBS)
    path = write(city, plane("1e7"))
    with pytest.raises(UnsafeSceneError, match="20,000,000 m wide"):
        raytrace.ray_traced_radio_map(path, base_stations=GBS)


@pytest.mark.parametrize("altitude_m", [0.0, -100.0, math.nan, math.inf])
def test_a_bad_altitude_is_refused_before_the_area_and_the_scene(altitude_m: float, tmp_path: Path) -> None:
    # the scene does not exist and the extent is over its limit: the altitude is named first
    with pytest.raises(ValueError, match=r"^altitude_m must be > 0 \(the flight altitude, e\.g\. 100\), got "):
        raytrace.ray_traced_radio_map(
            tmp_path / "nowhere.xml", altitude_m=altitude_m, extent=(0, 0, 60000, 10), base_stations=GBS
        )


def test_the_default_area_is_bounded_too() -> None:
    class Box:
        min, max = (-1e7, -10.0, 0.0), (1e7, 10.0, 5.0)

    class Loaded:
        class mi_scene:  # Mitsuba's attribute name
            @staticmethod
            def bbox() -> Box:
                return Box()

    with pytest.raises(ValueError, match=r"the scene's bounding box .* is 20,000,000 m wide"):
        raytrace.scene_extent(Loaded())


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scene", "city/scene.xml"], "<shape> type '../meshes/evil' is a path"),
        (["--scene", "empty", "--cell-m", "0.001", "--extent-m", "0", "0", "1000", "1000"], "1,000,000,000,000 cells"),
        (["--scene", "empty", "--cell-m", "nan", "--extent-m", "0", "0", "1000", "1000"], "cell_m=nan"),
        (["--scene", "empty", "--extent-m", "0", "0", "1e8", "1"], "over the limit of 50,000 m"),
    ],
)
def test_the_command_refuses_in_one_line(
    argv: list[str], message: str, city: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    write(city, '  <shape type="../meshes/evil"/>')
    monkeypatch.chdir(city.parent)
    assert exit_status([*argv, "--out", "x.npz"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("uamfleet-radio-map: error: ")
    assert not (city.parent / "x.npz").exists()


def test_the_docs_list_the_allowlist_and_the_limits() -> None:
    docs = (Path(__file__).resolve().parents[2] / "docs" / "inputs.md").read_text(encoding="utf-8")
    section = docs.partition("## Scenes")[2].partition("\n## ")[0]
    for tag, types in PLUGIN_TYPES.items():
        assert f"`{tag}`" in section, tag
        for kind in types:
            assert f"`{kind}`" in section, (tag, kind)
    for name in ("scene_bytes", "scene_shapes", "scene_extent_m", "map_cells"):
        default, _ = SIZE_LIMITS[name]
        assert f"| `{name}` | {default:,}" in section, name
    assert f"at most {MAX_INCLUDE_DEPTH} includes deep" in section
    assert f"at most {ELEMENTS_PER_SHAPE} XML elements per allowed shape" in section
    assert f"nested at most {MAX_NESTING} deep" in section
