"""Reader for Altair WinProp ASCII result files (I/O only).

Layout::

    ANTENNA <n>  NAME|LOCATION E N h|FREQUENCY MHz|POWER x dBm ...|ANTENNATYPE ...   (per antenna)
    LOWER_LEFT E N / UPPER_RIGHT E N / HEIGHT h / RESOLUTION r   (other header keys are ignored)
    BEGIN_DATA
    E N value        (cell centres, UTM metres; value = SINR in dB or "N.C." = not computed)
    END_DATA

Every data point is placed by its coordinates (not by its position in the file), which must lie on the
``RESOLUTION`` grid and cover it exactly once.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from uamfleet.radio.radio_map import BaseStation, RadioMap

NOT_COMPUTED = "N.C."
# Coordinates are printed with 5 decimals; anything further than this fraction of a cell from a grid node is
# a malformed file, not round-off.
_GRID_TOLERANCE = 1e-3


class WinPropFormatError(ValueError):
    """A WinProp ASCII file does not have the expected layout; the message names the line."""


def _fail(path: Path, lineno: int, line: str, problem: str) -> WinPropFormatError:
    return WinPropFormatError(f"{path}: line {lineno}: {problem}: {line.strip()!r}")


def _parse_floats(path: Path, lineno: int, line: str, tokens: Sequence[str], what: str) -> list[float]:
    try:
        return [float(tok) for tok in tokens]
    except ValueError:
        raise _fail(path, lineno, line, f"{what} must be numbers") from None


class _Header:
    def __init__(self) -> None:
        self.height_m: float | None = None
        self.resolution_m: float | None = None
        # antenna number -> field (NAME, LOCATION, ...) -> (line number, line, text after the field name)
        self.antennas: dict[int, dict[str, tuple[int, str, str]]] = {}

    def read(self, path: Path, lineno: int, line: str) -> None:
        tokens = line.split()
        if not tokens:
            return
        key = tokens[0]
        if key in ("HEIGHT", "RESOLUTION"):
            if len(tokens) != 2:
                raise _fail(path, lineno, line, f"{key} needs exactly one number")
            (value,) = _parse_floats(path, lineno, line, tokens[1:], key)
            if key == "HEIGHT":
                self.height_m = value
            elif value <= 0:
                raise _fail(path, lineno, line, "RESOLUTION must be > 0")
            else:
                self.resolution_m = value
        elif key == "ANTENNA":
            if len(tokens) < 3:
                raise _fail(path, lineno, line, "ANTENNA needs a number and a field (NAME, LOCATION, ...)")
            try:
                number = int(tokens[1])
            except ValueError:
                raise _fail(path, lineno, line, "the antenna number must be an integer") from None
            parts = line.split(None, 3)  # keeps NAME's inner spacing ("Site  6 Antenna 1")
            rest = parts[3].strip() if len(parts) > 3 else ""
            self.antennas.setdefault(number, {})[tokens[2]] = (lineno, line, rest)

    def base_stations(self, path: Path, e0: float, n0: float) -> tuple[BaseStation, ...]:
        stations = []
        for number in sorted(self.antennas):
            fields = self.antennas[number]
            if "LOCATION" not in fields:
                raise WinPropFormatError(f"{path}: ANTENNA {number} has no LOCATION line; add 'LOCATION E N h'")
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
        raise WinPropFormatError(f"{path}: line 1: the file is empty; expected a WinProp ASCII result file")
    begin = next((i for i, line in enumerate(lines) if line.strip() == "BEGIN_DATA"), None)
    if begin is None:
        raise WinPropFormatError(
            f"{path}: line {len(lines)}: reached the end of the file without a BEGIN_DATA line; "
            "is this a WinProp ASCII result file?"
        )
    end = next((i for i in range(begin + 1, len(lines)) if lines[i].strip() == "END_DATA"), None)
    if end is None:
        raise WinPropFormatError(
            f"{path}: line {len(lines)}: no END_DATA after BEGIN_DATA (line {begin + 1}); the file looks truncated"
        )
    for i in range(end + 1, len(lines)):
        if lines[i].strip():
            raise _fail(path, i + 1, lines[i], "unexpected text after END_DATA")
    return begin, end


def _parse_data(path: Path, lines: list[str], begin: int, end: int) -> tuple[np.ndarray, list[int]]:
    """Rows ``[E, N, value]`` (value NaN for N.C.) and the 1-based line number of each row."""
    linenos = [i + 1 for i in range(begin + 1, end) if lines[i].strip()]
    if not linenos:
        raise WinPropFormatError(f"{path}: line {begin + 1}: no data lines between BEGIN_DATA and END_DATA")
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
    try:
        text = path.read_text(encoding="ascii")
    except UnicodeDecodeError as exc:
        raise WinPropFormatError(f"{path}: not an ASCII text file ({exc}); expected a WinProp ASCII result") from None
    lines = text.splitlines()
    begin, end = _split_sections(path, lines)
    header = _Header()
    for i in range(begin):
        header.read(path, i + 1, lines[i])
    if header.resolution_m is None:
        raise WinPropFormatError(f"{path}: line {begin + 1}: no RESOLUTION line before BEGIN_DATA; add 'RESOLUTION r'")
    if header.height_m is None:
        raise WinPropFormatError(f"{path}: line {begin + 1}: no HEIGHT line before BEGIN_DATA; add 'HEIGHT h'")
    res = header.resolution_m

    data, linenos = _parse_data(path, lines, begin, end)
    e0, n0 = float(data[:, 0].min()), float(data[:, 1].min())
    fx = (data[:, 0] - e0) / res
    fy = (data[:, 1] - n0) / res
    ix, iy = np.rint(fx), np.rint(fy)
    off = (np.abs(fx - ix) > _GRID_TOLERANCE) | (np.abs(fy - iy) > _GRID_TOLERANCE)
    if off.any():
        k = linenos[int(np.flatnonzero(off)[0])]
        raise _fail(path, k, lines[k - 1], f"point is not on the {res:g} m RESOLUTION grid from ({e0}, {n0})")
    ix_i, iy_i = ix.astype(np.intp), iy.astype(np.intp)
    nx, ny = int(ix_i.max()) + 1, int(iy_i.max()) + 1
    flat = ix_i * ny + iy_i
    order = np.argsort(flat, kind="stable")
    dup = np.flatnonzero(np.diff(flat[order]) == 0)
    if dup.size:
        first, second = linenos[int(order[dup[0]])], linenos[int(order[dup[0] + 1])]
        raise _fail(path, second, lines[second - 1], f"duplicate grid point (also on line {first})")
    if flat.size != nx * ny:
        present = np.zeros(nx * ny, dtype=bool)
        present[flat] = True
        mx, my = divmod(int(np.flatnonzero(~present)[0]), ny)
        raise WinPropFormatError(
            f"{path}: lines {linenos[0]}-{linenos[-1]}: incomplete grid: {flat.size} points for a "
            f"{nx} x {ny} grid ({nx * ny} needed); first missing point "
            f"E={e0 + mx * res:.5f} N={n0 + my * res:.5f}"
        )
    sinr = np.empty(nx * ny)
    sinr[flat] = data[:, 2]
    return RadioMap(
        sinr_db=sinr.reshape(nx, ny),
        resolution_m=res,
        name=path.stem,
        altitude_m=header.height_m,
        base_stations=header.base_stations(path, e0, n0),
        utm_origin_m=(e0, n0),
        source=f"WinProp ASCII file {path.name}",
    )
