"""Reader for Altair WinProp ASCII result files (I/O only).

Layout::

    ANTENNA <n>  NAME|LOCATION E N h|FREQUENCY MHz|POWER x dBm ...|ANTENNATYPE ...   (per antenna)
    LOWER_LEFT E N / UPPER_RIGHT E N / HEIGHT h / RESOLUTION r   (other header keys are ignored)
    BEGIN_DATA
    E N value        (cell centres, UTM metres; value = SINR in dB or "N.C." = not computed)
    END_DATA

Every data point is placed by its coordinates (not by its position in the file), which must lie on the
``RESOLUTION`` grid and cover it exactly once. ``LOWER_LEFT`` / ``UPPER_RIGHT`` (optional, both or neither)
are the outer corners of the cells, half a cell beyond the first and last centres (the Berlin file:
392255 .. 395535 E for centres 392260 .. 395530); the data must fill exactly that grid. Header numbers must be
finite and each grid key (HEIGHT, RESOLUTION, LOWER_LEFT, UPPER_RIGHT) and antenna field appear once. Line
numbers in messages count newlines only, as an editor does.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from uamfleet.checks import ConfigError, check_size
from uamfleet.radio.radio_map import BaseStation, RadioMap

NOT_COMPUTED = "N.C."
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")  # anything but tab, newline and carriage return
_GRID_KEYS = {"HEIGHT": 1, "RESOLUTION": 1, "LOWER_LEFT": 2, "UPPER_RIGHT": 2}  # key -> how many numbers
# Coordinates are printed with 5 decimals; anything further than this fraction of a cell from a grid node is
# a malformed file, not round-off.
_GRID_TOLERANCE = 1e-3
BYTES_PER_POINT = 256
"""Bytes a data line may take on average (the Berlin file: 36): a file larger than this many bytes per cell of
the ``map_cells`` limit is refused before it is read (docs/inputs.md "Size limits of maps")."""


class WinPropFormatError(ValueError):
    """A WinProp ASCII file does not have the expected layout; the message names the line.

    ``lineno`` is the (first) 1-based line the message names, counted on newlines; ``line`` is that line's
    text (stripped) where the message quotes it, else None.
    """

    def __init__(self, message: str, lineno: int, line: str | None = None) -> None:
        super().__init__(message)
        self.lineno = lineno
        self.line = line


def _fail(path: Path, lineno: int, line: str, problem: str) -> WinPropFormatError:
    return WinPropFormatError(f"{path}: line {lineno}: {problem}: {line.strip()!r}", lineno, line.strip())


def _parse_floats(path: Path, lineno: int, line: str, tokens: Sequence[str], what: str) -> list[float]:
    try:
        values = [float(tok) for tok in tokens]
    except ValueError:
        raise _fail(path, lineno, line, f"{what} must be numbers") from None
    if not all(math.isfinite(v) for v in values):
        raise _fail(path, lineno, line, f"{what} must be finite numbers")
    return values


class _Header:
    def __init__(self) -> None:
        # key -> (line number, line, values) for the single-valued keys that shape the grid
        self.values: dict[str, tuple[int, str, list[float]]] = {}
        # antenna number -> field (NAME, LOCATION, ...) -> (line number, line, text after the field name)
        self.antennas: dict[int, dict[str, tuple[int, str, str]]] = {}

    def number(self, key: str) -> float | None:
        return self.values[key][2][0] if key in self.values else None

    def read(self, path: Path, lineno: int, line: str) -> None:
        tokens = line.split()
        if not tokens:
            return
        key = tokens[0]
        if key in _GRID_KEYS:
            count = _GRID_KEYS[key]
            if len(tokens) != count + 1:
                raise _fail(path, lineno, line, f"{key} needs exactly {'one number' if count == 1 else 'E N'}")
            if key in self.values:
                raise _fail(path, lineno, line, f"{key} given twice (also on line {self.values[key][0]})")
            values = _parse_floats(path, lineno, line, tokens[1:], key)
            if key == "RESOLUTION" and values[0] <= 0:
                raise _fail(path, lineno, line, "RESOLUTION must be > 0")
            self.values[key] = (lineno, line, values)
        elif key == "ANTENNA":
            if len(tokens) < 3:
                raise _fail(path, lineno, line, "ANTENNA needs a number and a field (NAME, LOCATION, ...)")
            try:
                number = int(tokens[1])
            except ValueError:
                raise _fail(path, lineno, line, "the antenna number must be an integer") from None
            parts = line.split(None, 3)  # keeps NAME's inner spacing ("Site  6 Antenna 1")
            rest = parts[3].strip() if len(parts) > 3 else ""
            fields = self.antennas.setdefault(number, {})
            if tokens[2] in fields:
                raise _fail(
                    path,
                    lineno,
                    line,
                    f"ANTENNA {number} {tokens[2]} given twice (also on line {fields[tokens[2]][0]})",
                )
            fields[tokens[2]] = (lineno, line, rest)

    def extent(self, path: Path, res: float) -> tuple[float, float, int, int, int, int] | None:
        """First cell centre (E, N) and grid size (nx, ny) of LOWER_LEFT..UPPER_RIGHT (cell corners), with the
        first and last of their two lines; None when the header gives neither."""
        given = [k for k in ("LOWER_LEFT", "UPPER_RIGHT") if k in self.values]
        if not given:
            return None
        if len(given) == 1:
            lineno, line, _ = self.values[given[0]]
            other = "UPPER_RIGHT" if given[0] == "LOWER_LEFT" else "LOWER_LEFT"
            raise _fail(path, lineno, line, f"{given[0]} without {other}; give both corners of the grid, or neither")
        (ll_line, _, (e_lo, n_lo)), (ur_line, ur_text, (e_hi, n_hi)) = (
            self.values["LOWER_LEFT"],
            self.values["UPPER_RIGHT"],
        )
        cells = ((e_hi - e_lo) / res, (n_hi - n_lo) / res)
        if not all(c >= 1 - _GRID_TOLERANCE and abs(c - round(c)) <= _GRID_TOLERANCE for c in cells):
            raise _fail(
                path, ur_line, ur_text,
                f"UPPER_RIGHT - LOWER_LEFT (line {ll_line}) = {e_hi - e_lo:g} x {n_hi - n_lo:g} m is not a positive "
                f"whole number of {res:g} m RESOLUTION cells",
            )  # fmt: skip
        first, last = min(ll_line, ur_line), max(ll_line, ur_line)
        return e_lo + res / 2, n_lo + res / 2, round(cells[0]), round(cells[1]), first, last

    def base_stations(self, path: Path, e0: float, n0: float) -> tuple[BaseStation, ...]:
        stations = []
        for number in sorted(self.antennas):
            fields = self.antennas[number]
            if "LOCATION" not in fields:
                first = min(entry[0] for entry in fields.values())
                raise WinPropFormatError(
                    f"{path}: line {first}: ANTENNA {number} has no LOCATION line; add "
                    f"'ANTENNA {number} LOCATION E N h' to its lines",
                    first,
                )
            lineno, line, rest = fields["LOCATION"]
            loc = rest.split()
            if len(loc) != 3:
                raise _fail(path, lineno, line, "LOCATION needs three numbers E N h")
            e, n, h = _parse_floats(path, lineno, line, loc, "LOCATION")
            kwargs: dict[str, float] = {}
            for key, arg in (("POWER", "power_dbm"), ("FREQUENCY", "frequency_mhz")):
                if key in fields:
                    lineno, line, rest = fields[key]
                    vals = rest.split()  # "40.000 dBm Output": the number comes first
                    if not vals:
                        raise _fail(path, lineno, line, f"{key} needs a number")
                    kwargs[arg] = _parse_floats(path, lineno, line, vals[:1], key)[0]
            name = fields["NAME"][2] if "NAME" in fields else f"Antenna {number}"
            # Rounded to a micrometre: the file gives millimetres, the subtraction adds float noise.
            stations.append(BaseStation(x_m=round(e - e0, 6), y_m=round(n - n0, 6), height_m=h, name=name, **kwargs))
        return tuple(stations)


def _split_sections(path: Path, lines: list[str]) -> tuple[int, int]:
    """Indices of the BEGIN_DATA and END_DATA lines."""
    if not any(line.strip() for line in lines):
        raise WinPropFormatError(f"{path}: line 1: the file is empty; expected a WinProp ASCII result file", 1)
    begin = next((i for i, line in enumerate(lines) if line.strip() == "BEGIN_DATA"), None)
    if begin is None:
        raise WinPropFormatError(
            f"{path}: line {len(lines)}: reached the end of the file without a BEGIN_DATA line; "
            "is this a WinProp ASCII result file?",
            len(lines),
        )
    end = next((i for i in range(begin + 1, len(lines)) if lines[i].strip() == "END_DATA"), None)
    if end is None:
        raise WinPropFormatError(
            f"{path}: line {len(lines)}: no END_DATA after BEGIN_DATA (line {begin + 1}); the file looks truncated",
            len(lines),
        )
    for i in range(end + 1, len(lines)):
        if lines[i].strip():
            raise _fail(path, i + 1, lines[i], "unexpected text after END_DATA")
    return begin, end


def _parse_data(path: Path, lines: list[str], begin: int, end: int) -> tuple[np.ndarray, list[int]]:
    """Rows ``[E, N, value]`` (value NaN for N.C.) and the 1-based line number of each row."""
    linenos = [i + 1 for i in range(begin + 1, end) if lines[i].strip()]
    if not linenos:
        raise WinPropFormatError(f"{path}: line {begin + 1}: no data lines between BEGIN_DATA and END_DATA", begin + 1)
    rows = [lines[k - 1].split() for k in linenos]
    bad = next((k for k, row in zip(linenos, rows, strict=True) if len(row) != 3), None)
    if bad is not None:
        raise _fail(path, bad, lines[bad - 1], "a data line needs exactly three fields 'E N value'")
    tokens = np.array(rows)  # [P, 3] str
    nc = tokens[:, 2] == NOT_COMPUTED
    tokens[nc, 2] = "nan"
    try:
        data = tokens.astype(np.float64)
    except ValueError:
        # Slow path only to find and name the offending line.
        for k, row in zip(linenos, rows, strict=True):
            _parse_floats(path, k, lines[k - 1], row[:2], "E and N")
            if row[2] != NOT_COMPUTED:
                _parse_floats(path, k, lines[k - 1], row[2:], f"the value (SINR in dB or {NOT_COMPUTED})")
        raise  # pragma: no cover - the loop above always finds the line
    finite = np.isfinite(data)
    finite[nc, 2] = True
    if not finite.all():
        k = linenos[int(np.flatnonzero(~finite.all(axis=1))[0])]
        raise _fail(path, k, lines[k - 1], f"values must be finite numbers or {NOT_COMPUTED}")
    return data, linenos


def read_winprop(path: str | os.PathLike[str]) -> RadioMap:
    """Read a WinProp ASCII SINR file into a :class:`RadioMap` in the world frame.

    World (0, 0) is the first grid point (min E, min N) and ``utm_origin_m`` records its UTM coordinates;
    antennas become base stations in that frame; ``altitude_m`` is the file's HEIGHT. Raises
    :class:`WinPropFormatError` (a ValueError) naming the offending line for any malformed input.
    """
    path = Path(path)
    size = path.stat().st_size
    what = f"the file ({size:,} bytes, at most {BYTES_PER_POINT} per grid point)"
    _check_size(path, 1, size / BYTES_PER_POINT, what, 0)
    lines = _read_lines(path)
    begin, end = _split_sections(path, lines)
    _check_size(path, begin + 2, end - begin - 1, f"the data ({end - begin - 1:,} data lines)")
    header = _Header()
    for i in range(begin):
        header.read(path, i + 1, lines[i])
    res, height = header.number("RESOLUTION"), header.number("HEIGHT")
    if res is None:
        raise WinPropFormatError(
            f"{path}: line {begin + 1}: no RESOLUTION line before BEGIN_DATA; add 'RESOLUTION r'", begin + 1
        )
    if height is None:
        raise WinPropFormatError(
            f"{path}: line {begin + 1}: no HEIGHT line before BEGIN_DATA; add 'HEIGHT h'", begin + 1
        )

    _check_declared_grid(path, header, res)
    data, linenos = _parse_data(path, lines, begin, end)
    e0, n0 = float(data[:, 0].min()), float(data[:, 1].min())
    sinr = _place_on_grid(path, lines, data, linenos, res, (e0, n0), header.extent(path, res))
    return RadioMap(
        sinr_db=sinr,
        resolution_m=res,
        name=path.stem,
        altitude_m=height,
        base_stations=header.base_stations(path, e0, n0),
        utm_origin_m=(e0, n0),
        source=f"WinProp ASCII file {path.name}",
    )


def _check_declared_grid(path: Path, header: _Header, res: float) -> None:
    """Refuse a LOWER_LEFT..UPPER_RIGHT grid over the ``map_cells`` limit before the data are parsed (whether it is
    a whole number of cells is checked with the data), naming the first of its two lines."""
    if "LOWER_LEFT" in header.values and "UPPER_RIGHT" in header.values:
        (e_lo, n_lo), (e_hi, n_hi) = header.values["LOWER_LEFT"][2], header.values["UPPER_RIGHT"][2]
        cells = max((e_hi - e_lo) / res, 0.0) * max((n_hi - n_lo) / res, 0.0)
        first = min(header.values["LOWER_LEFT"][0], header.values["UPPER_RIGHT"][0])
        area = f"{e_hi - e_lo:g} x {n_hi - n_lo:g} m"
        _check_size(path, first, cells, f"LOWER_LEFT..UPPER_RIGHT ({area} of {res:g} m cells)")


def _check_size(path: Path, lineno: int, cells: float, what: str, unit_bytes: float = 8) -> None:
    """:func:`~uamfleet.checks.check_size` of ``map_cells`` as a :class:`WinPropFormatError` naming the line."""
    try:
        check_size("map_cells", cells, what, unit_bytes)
    except ConfigError as err:
        raise WinPropFormatError(f"{path}: line {lineno}: {err}", lineno) from None


def _read_lines(path: Path) -> list[str]:
    """The file's lines, split on newlines only (so that line numbers match an editor's)."""
    raw = path.read_bytes()
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        lineno = raw.count(b"\n", 0, exc.start) + 1
        raise WinPropFormatError(
            f"{path}: line {lineno}: byte 0x{raw[exc.start]:02x} is not ASCII, so this is not an ASCII text file; "
            "expected a WinProp ASCII result",
            lineno,
        ) from None
    control = _CONTROL.search(text)
    if control is not None:
        lineno = text.count("\n", 0, control.start()) + 1
        raise WinPropFormatError(
            f"{path}: line {lineno}: control character {control.group()!r} in the text; a WinProp ASCII file holds "
            "printable characters, tabs and newlines only",
            lineno,
        )
    lines = [line.rstrip("\r") for line in text.split("\n")]
    return lines[:-1] if len(lines) > 1 and not lines[-1] else lines  # no line after the final newline


def _place_on_grid(
    path: Path,
    lines: list[str],
    data: np.ndarray,
    linenos: list[int],
    res: float,
    first: tuple[float, float],
    extent: tuple[float, float, int, int, int, int] | None,
) -> np.ndarray:
    """[nx, ny] SINR raster with each row of ``data`` at its coordinates; every grid point exactly once.

    Indices stay floats (exact whole numbers) until the grid is known to be complete, so that a corrupted
    coordinate (1e300, or a tiny RESOLUTION) gives a message instead of an integer overflow or a huge allocation.
    """
    e0, n0 = first
    fx = (data[:, 0] - e0) / res
    fy = (data[:, 1] - n0) / res
    ix, iy = np.rint(fx), np.rint(fy)
    off = (np.abs(fx - ix) > _GRID_TOLERANCE) | (np.abs(fy - iy) > _GRID_TOLERANCE)
    if off.any():
        k = linenos[int(np.flatnonzero(off)[0])]
        raise _fail(path, k, lines[k - 1], f"point is not on the {res:g} m RESOLUTION grid from ({e0}, {n0})")
    nx, ny = float(ix.max()) + 1, float(iy.max()) + 1
    if extent is not None:
        _check_extent(path, lines, linenos, res, (e0, n0, nx, ny), extent, (ix, iy))
    order = np.lexsort((iy, ix))  # by E, then N: the file's usual order
    sx, sy = ix[order], iy[order]
    dup = np.flatnonzero((np.diff(sx) == 0) & (np.diff(sy) == 0))
    if dup.size:
        first_k, second = linenos[int(order[dup[0]])], linenos[int(order[dup[0] + 1])]
        raise _fail(path, second, lines[second - 1], f"duplicate grid point (also on line {first_k})")
    if ix.size != nx * ny:
        # Distinct points sorted by (E, N) must be (0, 0), (0, 1), ...: the first gap is the first missing point.
        rank = np.arange(ix.size)
        gaps = np.flatnonzero((sx != rank // ny) | (sy != rank % ny))
        mx, my = divmod(float(gaps[0]) if gaps.size else float(ix.size), ny)
        raise WinPropFormatError(
            f"{path}: lines {linenos[0]}-{linenos[-1]}: incomplete grid: {ix.size} points for a "
            f"{_count(nx)} x {_count(ny)} grid ({_count(nx * ny)} needed); first missing point "
            f"E={e0 + mx * res:.5f} N={n0 + my * res:.5f}",
            linenos[0],
        )
    if nx < 2 or ny < 2:
        raise WinPropFormatError(
            f"{path}: lines {linenos[0]}-{linenos[-1]}: a {nx:.0f} x {ny:.0f} grid; a radio map needs at least "
            "2 points along E and along N",
            linenos[0],
        )
    sinr = np.empty((int(nx), int(ny)))
    sinr[ix.astype(np.intp), iy.astype(np.intp)] = data[:, 2]
    return sinr


def _count(value: float) -> str:
    return f"{value:.0f}" if value < 1e15 else f"{value:.3g}"


def _check_extent(
    path: Path,
    lines: list[str],
    linenos: list[int],
    res: float,
    data_grid: tuple[float, float, float, float],
    extent: tuple[float, float, int, int, int, int],
    index: tuple[np.ndarray, np.ndarray],
) -> None:
    """The data's grid must be the one LOWER_LEFT..UPPER_RIGHT describes (cell corners around the centres)."""
    e0, n0, nx, ny = data_grid
    he, hn, hnx, hny, first_line, last_line = extent
    label = f"lines {first_line}-{last_line} (LOWER_LEFT/UPPER_RIGHT)"
    # Data cell indices on the header's grid: a point outside it is named by its line.
    hx, hy = index[0] + round((e0 - he) / res), index[1] + round((n0 - hn) / res)
    outside = (hx < 0) | (hx >= hnx) | (hy < 0) | (hy >= hny)
    if outside.any():
        k = linenos[int(np.flatnonzero(outside)[0])]
        raise _fail(
            path, k, lines[k - 1],
            f"point lies outside the header's extent: {label} give a {hnx} x {hny} grid of {res:g} m cells "
            f"with centres from E={he:.5f} N={hn:.5f}",
        )  # fmt: skip
    shifted = abs(e0 - he) > _GRID_TOLERANCE * res or abs(n0 - hn) > _GRID_TOLERANCE * res
    if shifted or (nx, ny) != (hnx, hny):
        raise WinPropFormatError(
            f"{path}: {label}: the header's extent is {hnx * res:g} x {hny * res:g} m, a {hnx} x {hny} grid of "
            f"{res:g} m cells with centres from E={he:.5f} N={hn:.5f}, but the data (lines {linenos[0]}-"
            f"{linenos[-1]}) span a {nx:.0f} x {ny:.0f} grid from E={e0:.5f} N={n0:.5f}; fix LOWER_LEFT/UPPER_RIGHT "
            "or the data",
            first_line,
        )
