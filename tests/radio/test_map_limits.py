"""Maps declare their size before anything is allocated (issue 39, part 3; docs/inputs.md "Size limits of maps").

A crafted ``.npz`` of a few kB whose headers declare tens of GiB, a map whose ``side_m`` makes a block map of
74.5 GiB, a WinProp header of a continent: each is refused with one line naming the file and the size it would
need, before the array is read; the limits are raised by their environment variables.
"""

from __future__ import annotations

import io
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from uamfleet.checks import ConfigError
from uamfleet.radio import RadioMap, WinPropFormatError, read_radio_map_npz, read_winprop, save_radio_map_npz
from uamfleet.radio import raytrace

MiB = 2**20


def npy(array: np.ndarray | None = None, shape: tuple[int, ...] = (), dtype: str = "<f8") -> bytes:
    """The bytes of a ``.npy`` member: ``array``, or a header declaring ``shape`` of ``dtype`` over 64 bytes."""
    buffer = io.BytesIO()
    if array is not None:
        np.lib.format.write_array(buffer, np.asarray(array))
    else:
        header = {"descr": dtype, "fortran_order": False, "shape": shape}
        np.lib.format.write_array_header_1_0(buffer, header)
        buffer.write(b"\0" * 64)
    return buffer.getvalue()


def crafted_npz(path: Path, side_m: float = 100.0, resolution_m: float = 10.0, **declared: tuple) -> Path:
    """A map in the format of :func:`save_radio_map_npz` whose members named in ``declared`` are only headers
    (``name=(shape, dtype)``); an 11 x 11 raster otherwise."""
    fields = {
        "format": np.array(raytrace.NPZ_FORMAT),
        "sinr_db": np.zeros((11, 11)),
        "resolution_m": np.array(resolution_m),
        "origin_m": np.array([0.0, 0.0]),
        "side_m": np.array(side_m),
        "altitude_m": np.array(100.0),
        "name": np.array("crafted"),
        "is_estimate": np.array(False),
        "source": np.array(""),
        "bs_values": np.zeros((0, len(raytrace._BS_FIELDS))),
        "bs_name": np.array([], dtype=str),
    }
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, value in fields.items():
            body = npy(shape=declared[name][0], dtype=declared[name][1]) if name in declared else npy(value)
            archive.writestr(f"{name}.npy", body)
    return path


def refusal(path: Path) -> tuple[str, int]:
    """The ConfigError's message of reading ``path`` and the peak of Python-tracked memory while reading it."""
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError) as err:
            read_radio_map_npz(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    message = str(err.value)
    assert "\n" not in message
    return message, peak


def small_map(**kwargs) -> RadioMap:
    return RadioMap(sinr_db=np.zeros((11, 11)), **{"resolution_m": 10.0, **kwargs})


def test_an_npz_declaring_a_huge_raster_is_refused_before_it_is_read(tmp_path: Path) -> None:
    # 60,000 x 60,000 float64 = 3.6e9 * 8 bytes = 26.8 GiB, in a file of 2 kB
    path = crafted_npz(tmp_path / "huge.npz", sinr_db=((60_000, 60_000), "<f8"))
    assert path.stat().st_size < 4096
    message, peak = refusal(path)
    assert str(path) in message
    assert "60000 x 60000" in message and "3,600,000,000 cells" in message and "(26.8 GiB)" in message
    assert "UAMFLEET_MAX_MAP_CELLS" in message
    assert peak < 16 * MiB


def test_an_npz_declaring_a_huge_string_is_refused(tmp_path: Path) -> None:
    # ten strings of 10^8 characters: 4e9 bytes (3.7 GiB), 5e8 raster cells' worth
    path = crafted_npz(tmp_path / "long.npz", source=((10,), "<U100000000"))
    message, peak = refusal(path)
    assert str(path) in message and "'source'" in message and "(3.7 GiB)" in message
    assert peak < 16 * MiB


def test_an_npz_with_side_m_1e7_is_refused(tmp_path: Path) -> None:
    # On a 10^7 m side a block map of 100 m blocks has 10^5 x 10^5 blocks: 74.5 GiB of float64.
    path = crafted_npz(tmp_path / "wide.npz", side_m=1e7)
    message, peak = refusal(path)
    assert str(path) in message and "side_m=1e+07" in message and "50,000" in message
    assert "UAMFLEET_MAX_SCENE_EXTENT_M" in message
    assert peak < 16 * MiB
    with pytest.raises(ConfigError, match=r"side_m=1e\+07.*over the limit of 50,000"):
        small_map(side_m=1e7)


def test_a_fine_resolution_over_a_wide_side_is_refused() -> None:
    # side 40 km at 1 mm: block maps and path graphs of 4e7 x 4e7 cells, whatever the raster's own size
    with pytest.raises(ConfigError, match=r"side_m=40000 at resolution_m=0\.001.*40,000,001 x 40,000,001 cells"):
        RadioMap(sinr_db=np.zeros((3, 3)), resolution_m=0.001, side_m=40_000.0)


def test_a_raster_spanning_or_placed_beyond_the_extent_limit_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"spans 1e\+06 m"):
        RadioMap(sinr_db=np.zeros((3, 3)), resolution_m=5e5, side_m=1000.0)
    with pytest.raises(ConfigError, match=r"origin_m=\(1e\+09, 0\) lies 1e\+09 m out"):
        small_map(origin_m=(1e9, 0.0))


def test_a_block_map_over_the_limit_is_refused() -> None:
    radio = RadioMap(sinr_db=np.zeros((3, 3)), resolution_m=1.0, side_m=3000.0)
    with pytest.raises(ConfigError, match=r"block map of 'RadioMap'|300,000 x 300,000 blocks of 0\.01 m"):
        radio.block_map(0.01)
    assert radio.block_map(100.0).shape == (30, 30)


def test_the_limits_are_raised_by_their_environment_variables(tmp_path: Path, monkeypatch) -> None:
    path = save_radio_map_npz(small_map(), tmp_path / "fine.npz")  # 121 cells
    monkeypatch.setenv("UAMFLEET_MAX_MAP_CELLS", "100")
    with pytest.raises(ConfigError, match=r"fine\.npz.*121 cells.*over the limit of 100"):
        read_radio_map_npz(path)
    monkeypatch.setenv("UAMFLEET_MAX_MAP_CELLS", "200")
    assert read_radio_map_npz(path).shape == (11, 11)
    monkeypatch.delenv("UAMFLEET_MAX_MAP_CELLS")
    # a 60 km side at 100 m cells (601 x 601 blocks at most): over the default 50 km, fine once raised
    wide = dict(resolution_m=100.0, side_m=60_000.0)
    with pytest.raises(ConfigError, match=r"side_m=60000.*UAMFLEET_MAX_SCENE_EXTENT_M"):
        small_map(**wide)
    monkeypatch.setenv("UAMFLEET_MAX_SCENE_EXTENT_M", "100000")
    radio = small_map(**wide)
    assert radio.side_m == 60_000.0
    assert read_radio_map_npz(save_radio_map_npz(radio, tmp_path / "wide.npz")).side_m == 60_000.0


WINPROP_HEADER = """HEIGHT\t100.000
RESOLUTION\t{res}
{corners}
BEGIN_DATA"""
ROWS = ["0 0 1.0", "0 10 2.0", "10 0 3.0", "10 10 4.0"]


def winprop(tmp_path: Path, corners: str = "", res: float = 10.0, rows: list[str] = ROWS) -> Path:
    path = tmp_path / "map.txt"
    path.write_text("\n".join([WINPROP_HEADER.format(res=res, corners=corners), *rows, "END_DATA"]) + "\n")
    return path


def test_a_winprop_header_declaring_a_huge_grid_is_refused_before_the_data(tmp_path: Path) -> None:
    corners = "LOWER_LEFT\t-5 -5\nUPPER_RIGHT\t999995 999995"  # 10^5 x 10^5 cells of 10 m: 74.5 GiB
    tracemalloc.start()
    try:
        with pytest.raises(WinPropFormatError) as err:
            read_winprop(winprop(tmp_path, corners))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    message = str(err.value)
    assert message.startswith(f"{tmp_path / 'map.txt'}: line 3: LOWER_LEFT..UPPER_RIGHT (1e+06 x 1e+06 m of 10 m ")
    assert "10,000,000,000 cells" in message and "(74.5 GiB)" in message and "UAMFLEET_MAX_MAP_CELLS" in message
    assert err.value.lineno == 3 and "\n" not in message and peak < 16 * MiB


def test_a_winprop_file_is_bounded_by_its_lines_and_bytes(tmp_path: Path, monkeypatch) -> None:
    path = winprop(tmp_path)
    assert read_winprop(path).shape == (2, 2)
    monkeypatch.setenv("UAMFLEET_MAX_MAP_CELLS", "3")
    with pytest.raises(WinPropFormatError, match=r"map\.txt: line 5: the data \(4 data lines\) needs 4 cells.*of 3"):
        read_winprop(path)
    monkeypatch.setenv("UAMFLEET_MAX_MAP_CELLS", "1")  # 1 cell: at most 256 bytes of file
    padded = winprop(tmp_path, rows=[*ROWS[:3], ROWS[3] + " " * 300])
    with pytest.raises(WinPropFormatError, match=r"map\.txt: line 1: the file \([0-9]{3} bytes, at most 256 per grid"):
        read_winprop(padded)


def test_docs_name_each_map_limit_with_its_default_and_variable() -> None:
    from uamfleet.checks import SIZE_LIMITS

    text = (Path(__file__).resolve().parents[2] / "docs" / "inputs.md").read_text(encoding="utf-8")
    section = text.split("## Size limits of maps", 1)[1].split("\n## ", 1)[0]
    for name in ("map_cells", "scene_extent_m"):
        default = SIZE_LIMITS[name][0]
        assert f"| `{name}` | {default:,} | `UAMFLEET_MAX_{name.upper()}` |" in section


def test_a_synthetic_map_is_bounded_before_its_grid_is_made() -> None:
    from uamfleet.radio import BaseStation
    from uamfleet.radio.channel_3gpp import expected_sinr_map_3gpp

    tracemalloc.start()
    try:
        with pytest.raises(ConfigError, match=r"^radio map '3gpp' \(a 1000001 x 1000001 raster\).*\(7450\.6 GiB\)"):
            expected_sinr_map_3gpp([BaseStation(0.0, 0.0, 20.0)], side_m=1e6, resolution_m=1.0)
        assert tracemalloc.get_traced_memory()[1] < 16 * MiB
    finally:
        tracemalloc.stop()


def test_a_heading_table_is_bounded_before_its_padded_raster_is_made() -> None:
    radio = small_map()  # 11 x 11 cells of 10 m
    with pytest.raises(
        ConfigError, match=r"heading table .*step_m=1e\+06: a raster padded by 100,001\).*\(298\.1 GiB\)"
    ):
        radio.heading_segment_min_sinr(1e6)  # (11 + 2 x 100,001)^2 cells of float64
    with pytest.raises(ValueError, match=r"num_headings=1000000000 is too large: at most 360"):
        radio.heading_segment_min_sinr(10.0, 10**9)
    assert radio.heading_segment_min_sinr(10.0).shape == (16, 11, 11)
