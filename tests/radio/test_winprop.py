"""WinProp ASCII reader: a round trip on a small drawn file and every malformed case."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from uamfleet.radio import WinPropFormatError, read_winprop

HEADER = """VERSION\t2020-38079
ANTENNA 2\tNAME\tSite  B Antenna 1
ANTENNA 2\tLOCATION\t1030.500 2010.250 15.000
ANTENNA 2\tFREQUENCY\t2145.000
ANTENNA 2\tPOWER\t43.000 dBm Output
ANTENNA 2\tANTENNATYPE\tISO
ANTENNA 1\tNAME\tSite  A Antenna 1
ANTENNA 1\tLOCATION\t1000.000 2000.000 20.000
ANTENNA 1\tFREQUENCY\t2115.000
ANTENNA 1\tPOWER\t40.000 dBm Output
ANTENNA 1\tANTENNATYPE\tISO
LOWER_LEFT\t995.00000000 1995.00000000
UPPER_RIGHT\t1025.00000000 2015.00000000
HEIGHT\t100.000
TIME_STEP\t0.000
RESOLUTION\t10.00000000

BEGIN_DATA"""  # BEGIN_DATA is line 18: the first data line is line 19

# 3 x 2 grid: E in {1000, 1010, 1020}, N in {2000, 2010}; value = 10 * ix + iy, cell (1, 1) not computed.
GOOD_ROWS = [
    "1000.00000 2000.00000 0.0000",
    "1000.00000 2010.00000 1.0000",
    "1010.00000 2000.00000 10.0000",
    "1010.00000 2010.00000 N.C.",
    "1020.00000 2000.00000 20.0000",
    "1020.00000 2010.00000 -21.2500",
]
FIRST_DATA_LINE = 19


def write(tmp_path: Path, rows: list[str], header: str = HEADER, end: str = "END_DATA") -> Path:
    path = tmp_path / "map.txt"
    path.write_text("\n".join([header, *rows, end]) + "\n")
    return path


def test_round_trip(tmp_path: Path) -> None:
    radio = read_winprop(write(tmp_path, GOOD_ROWS))
    expected = np.array([[0.0, 1.0], [10.0, np.nan], [20.0, -21.25]])
    np.testing.assert_array_equal(radio.sinr_db, expected)
    assert radio.resolution_m == 10.0
    assert radio.origin_m == (0.0, 0.0)
    assert radio.utm_origin_m == (1000.0, 2000.0)
    assert radio.altitude_m == 100.0
    assert radio.side_m == 10.0  # min(2 * 10, 1 * 10)
    assert radio.name == "map"
    # Antennas sorted by number, in the world frame (minus the first data point).
    a, b = radio.base_stations
    assert (a.name, a.x_m, a.y_m, a.height_m, a.power_dbm, a.frequency_mhz) == (
        "Site  A Antenna 1",
        0,
        0,
        20,
        40,
        2115,
    )
    assert (b.name, b.x_m, b.y_m, b.height_m, b.power_dbm, b.frequency_mhz) == (
        "Site  B Antenna 1",
        30.5,
        10.25,
        15,
        43,
        2145,
    )


def test_order_does_not_matter(tmp_path: Path) -> None:
    shuffled = [GOOD_ROWS[i] for i in (5, 2, 0, 3, 1, 4)]
    a = read_winprop(write(tmp_path, shuffled))
    b = read_winprop(write(tmp_path, GOOD_ROWS))
    np.testing.assert_array_equal(a.sinr_db, b.sinr_db)


def test_no_antennas_and_blank_data_lines(tmp_path: Path) -> None:
    header = "HEIGHT 50\nRESOLUTION 10\nBEGIN_DATA"
    radio = read_winprop(write(tmp_path, [*GOOD_ROWS[:3], "", *GOOD_ROWS[3:]], header=header))
    assert radio.base_stations == ()
    assert radio.altitude_m == 50.0
    assert radio.shape == (3, 2)


def replace_row(k: int, text: str) -> list[str]:
    rows = list(GOOD_ROWS)
    rows[k] = text
    return rows


@pytest.mark.parametrize(
    ("rows", "line", "match"),
    [
        (replace_row(2, "1010.00000 2000.00000 abc"), FIRST_DATA_LINE + 2, "numbers"),
        (replace_row(4, "1020.00000 2000.00000"), FIRST_DATA_LINE + 4, "three fields"),
        (replace_row(1, "1000.00000 2010.00000 1.0 7"), FIRST_DATA_LINE + 1, "three fields"),
        (replace_row(3, "1010.00000 2000.00000 3.0"), FIRST_DATA_LINE + 3, "duplicate"),
        (replace_row(5, "1020.00000 2013.00000 1.0"), FIRST_DATA_LINE + 5, "not on the 10 m"),
        (replace_row(0, "1000.00000 abc 1.0"), FIRST_DATA_LINE, "numbers"),
        (replace_row(0, "1000.00000 2000.00000 nan"), FIRST_DATA_LINE, "finite"),
        (GOOD_ROWS[:-1], FIRST_DATA_LINE, "incomplete grid"),
    ],
)
def test_malformed_data_names_the_line(tmp_path: Path, rows: list[str], line: int, match: str) -> None:
    with pytest.raises(WinPropFormatError, match=match) as info:
        read_winprop(write(tmp_path, rows))
    assert f"line {line}" in str(info.value) or f"lines {line}-" in str(info.value)
    assert isinstance(info.value, ValueError)


def test_incomplete_grid_names_the_missing_point(tmp_path: Path) -> None:
    with pytest.raises(WinPropFormatError, match=r"E=1010\.00000 N=2010\.00000"):
        read_winprop(write(tmp_path, [r for r in GOOD_ROWS if "N.C." not in r]))


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.txt"
    path.write_text("\n  \n")
    with pytest.raises(WinPropFormatError, match="line 1: the file is empty"):
        read_winprop(path)


def test_no_begin_data(tmp_path: Path) -> None:
    path = tmp_path / "nobegin.txt"
    path.write_text(HEADER.replace("BEGIN_DATA", "") + "\n".join(GOOD_ROWS))
    with pytest.raises(WinPropFormatError, match=r"line \d+: .*without a BEGIN_DATA"):
        read_winprop(path)


def test_no_end_data(tmp_path: Path) -> None:
    with pytest.raises(WinPropFormatError, match=r"line 25: no END_DATA"):
        read_winprop(write(tmp_path, GOOD_ROWS, end=""))


def test_text_after_end_data(tmp_path: Path) -> None:
    with pytest.raises(WinPropFormatError, match=r"line 26: unexpected text after END_DATA"):
        read_winprop(write(tmp_path, GOOD_ROWS, end="END_DATA\nBEGIN_DATA"))


@pytest.mark.parametrize(
    ("old", "new", "line", "match"),
    [
        ("RESOLUTION\t10.00000000", "RESOLUTION\tten", 16, "RESOLUTION must be numbers"),
        ("RESOLUTION\t10.00000000", "RESOLUTION\t-10", 16, "RESOLUTION must be > 0"),
        ("RESOLUTION\t10.00000000", "", 18, "no RESOLUTION"),
        ("HEIGHT\t100.000", "", 18, "no HEIGHT"),
        ("1000.000 2000.000 20.000", "1000.000 2000.000", 8, "LOCATION needs three numbers"),
        ("43.000 dBm", "high dBm", 5, "POWER must be numbers"),
        ("ANTENNA 2\tNAME", "ANTENNA two\tNAME", 2, "antenna number"),
    ],
)
def test_malformed_header_names_the_line(tmp_path: Path, old: str, new: str, line: int, match: str) -> None:
    assert old in HEADER
    with pytest.raises(WinPropFormatError, match=match) as info:
        read_winprop(write(tmp_path, GOOD_ROWS, header=HEADER.replace(old, new)))
    assert f"line {line}" in str(info.value)


def test_antenna_without_location(tmp_path: Path) -> None:
    header = HEADER.replace("ANTENNA 1\tLOCATION\t1000.000 2000.000 20.000\n", "")
    with pytest.raises(WinPropFormatError, match="ANTENNA 1 has no LOCATION"):
        read_winprop(write(tmp_path, GOOD_ROWS, header=header))


def test_binary_byte_names_its_line(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD_ROWS)
    raw = bytearray(path.read_bytes())
    raw[raw.index(b"1010.00000 2010.00000")] = 0xB1  # a flipped high bit on data line 22
    path.write_bytes(bytes(raw))
    with pytest.raises(WinPropFormatError, match=r"line 22: byte 0xb1 is not ASCII"):
        read_winprop(path)


def test_binary_file(tmp_path: Path) -> None:
    path = tmp_path / "map.bin"
    path.write_bytes(b"\xff\xfe\x00BEGIN_DATA")
    with pytest.raises(WinPropFormatError, match="not an ASCII text file"):
        read_winprop(path)


# ---- the header's extent (LOWER_LEFT / UPPER_RIGHT: corners of the cells around the data's centres) ------

GRID_3X3 = [f"{1000 + 10 * i:.5f} {2000 + 10 * j:.5f} {10 * i + j:.4f}" for i in range(3) for j in range(3)]


def header_with(lower_left: str, upper_right: str) -> str:
    return HEADER.replace("LOWER_LEFT\t995.00000000 1995.00000000", lower_left).replace(
        "UPPER_RIGHT\t1025.00000000 2015.00000000", upper_right
    )


def test_extent_that_matches_the_data(tmp_path: Path) -> None:
    radio = read_winprop(write(tmp_path, GRID_3X3, header=header_with("LOWER_LEFT 995 1995", "UPPER_RIGHT 1025 2025")))
    np.testing.assert_array_equal(radio.sinr_db, [[0, 1, 2], [10, 11, 12], [20, 21, 22]])


@pytest.mark.parametrize(
    ("lower_left", "upper_right", "rows", "match"),
    [
        # A 60 x 60 m extent (a 6 x 6 grid) around 3 x 3 data: the header and the data disagree.
        (
            "LOWER_LEFT 995 1995",
            "UPPER_RIGHT 1055 2055",
            GRID_3X3,
            r"lines 12-13 \(LOWER_LEFT/UPPER_RIGHT\): the header's extent is 60 x 60 m, a 6 x 6 grid of 10 m cells "
            r"with centres from E=1000.00000 N=2000.00000, but the data \(lines 19-27\) span a 3 x 3 grid",
        ),
        # The same size, shifted by one cell: every centre is off by 10 m.
        ("LOWER_LEFT 1005 1995", "UPPER_RIGHT 1035 2025", GRID_3X3, r"line 19: point lies outside the header's extent"),
        ("LOWER_LEFT 995 1995", "UPPER_RIGHT 1025 2020", GRID_3X3, r"line 13: .*30 x 25 m is not a positive whole"),
        ("LOWER_LEFT 1025 2025", "UPPER_RIGHT 995 1995", GRID_3X3, r"line 13: .*-30 x -30 m is not a positive whole"),
        ("LOWER_LEFT 995 1995", "UPPER_RIGHT 1025", GRID_3X3, r"line 13: UPPER_RIGHT needs exactly E N"),
        ("LOWER_LEFT 995 1995", "UPPER_RIGHT 1025 inf", GRID_3X3, r"line 13: UPPER_RIGHT must be finite numbers"),
        ("LOWER_LEFT 995 1995", "", GRID_3X3, r"line 12: LOWER_LEFT without UPPER_RIGHT"),
    ],
)
def test_extent_that_disagrees_names_the_lines(
    tmp_path: Path, lower_left: str, upper_right: str, rows: list[str], match: str
) -> None:
    with pytest.raises(WinPropFormatError, match=match):
        read_winprop(write(tmp_path, rows, header=header_with(lower_left, upper_right)))


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("HEIGHT\t100.000", "HEIGHT\tnan", r"line 14: HEIGHT must be finite numbers"),
        ("RESOLUTION\t10.00000000", "RESOLUTION\tinf", r"line 16: RESOLUTION must be finite numbers"),
        ("TIME_STEP\t0.000", "RESOLUTION 10", r"line 16: RESOLUTION given twice \(also on line 15\)"),
        ("ANTENNA 1\tPOWER", "ANTENNA 1\tFREQUENCY", r"line 10: ANTENNA 1 FREQUENCY given twice \(also on line 9\)"),
        ("1000.000 2000.000 20.000", "1000.000 nan 20.000", r"line 8: LOCATION must be finite numbers"),
    ],
)
def test_header_numbers_are_finite_and_given_once(tmp_path: Path, old: str, new: str, match: str) -> None:
    assert old in HEADER
    with pytest.raises(WinPropFormatError, match=match):
        read_winprop(write(tmp_path, GOOD_ROWS, header=HEADER.replace(old, new, 1)))


def test_far_away_point_is_reported_without_a_huge_grid(tmp_path: Path) -> None:
    # A corrupted coordinate 1e300 m away: named as an incomplete grid, not an overflow or a huge allocation.
    rows = replace_row(5, "1020.00000 1e300 -21.25")
    header = "HEIGHT 50\nRESOLUTION 10\nBEGIN_DATA"
    with pytest.raises(WinPropFormatError, match=r"incomplete grid: 6 points for a 3 x 1e\+299 grid"):
        read_winprop(write(tmp_path, rows, header=header))


def test_single_row_grid(tmp_path: Path) -> None:
    header = "HEIGHT 50\nRESOLUTION 10\nBEGIN_DATA"  # no extent: the data alone decide the grid
    with pytest.raises(WinPropFormatError, match=r"lines 4-6: a 3 x 1 grid; a radio map needs at least 2 points"):
        read_winprop(write(tmp_path, GOOD_ROWS[::2], header=header))


@pytest.mark.parametrize("char", ["\x00", "\x1c", "\x0c", "\x7f"])
def test_control_characters_name_their_line(tmp_path: Path, char: str) -> None:
    # NumPy would drop a trailing NUL from "6.718\x00" and str.split() takes \x1c for a space: neither is data.
    rows = replace_row(2, f"1010.00000 2000.00000 10.0000{char}")
    with pytest.raises(WinPropFormatError, match=rf"line {FIRST_DATA_LINE + 2}: control character") as info:
        read_winprop(write(tmp_path, rows))
    assert info.value.lineno == FIRST_DATA_LINE + 2


def test_crlf_line_ends_and_the_error_attributes(tmp_path: Path) -> None:
    path = tmp_path / "map.txt"
    path.write_bytes(write(tmp_path, GOOD_ROWS).read_bytes().replace(b"\n", b"\r\n"))
    np.testing.assert_array_equal(read_winprop(path).sinr_db, read_winprop(write(tmp_path, GOOD_ROWS)).sinr_db)
    path.write_bytes(write(tmp_path, replace_row(4, "1020.00000 2000.00000 x")).read_bytes().replace(b"\n", b"\r\n"))
    with pytest.raises(WinPropFormatError) as info:
        read_winprop(path)
    assert (info.value.lineno, info.value.line) == (FIRST_DATA_LINE + 4, "1020.00000 2000.00000 x")
