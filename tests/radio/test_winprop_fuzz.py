"""Fuzz test of the WinProp reader: seeded mutations of a valid file (truncations, flipped bits, replaced bytes,
swapped header values, deleted / duplicated / swapped lines). Each mutated file must give either

- a :class:`WinPropFormatError` whose ``lineno`` is a line of the mutated file (and whose quoted ``line``, when
  there is one, is that line's text), or
- a correct map: the original grid (same shape, resolution and origin, a mutation cannot move the grid without
  the header and the data disagreeing) holding, cell by cell, the value the mutated file's data line gives
  there, as an independent naive parser reads it; so it differs from the original only in cells whose data
  lines the mutation changed, and equals it where the mutation changed nothing that matters (a swap of two
  data lines, a changed antenna name, an unknown header key).

Never another exception, and never a NaN where the file gives a number.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from uamfleet.radio import WinPropFormatError, read_winprop

RES = 10.0
E0, N0 = 392260.0, 5816868.0  # the Berlin file's first centre
NX, NY = 7, 6
HEADER_KEYS = ("LOWER_LEFT", "UPPER_RIGHT", "HEIGHT", "RESOLUTION")


def original_text() -> str:
    rng = np.random.default_rng(0)
    lines = ["VERSION\t2020-38079", "DATE\t2024-08-27, 00:04:45 (+0800)"]
    for a, (e, n, h) in enumerate([(392300.5, 5816900.25, 20.0), (392310.0, 5816890.0, 15.0)], start=1):
        lines += [
            f"ANTENNA {a}\tNAME\tSite  {a} Antenna 1",
            f"ANTENNA {a}\tLOCATION\t{e:.3f} {n:.3f} {h:.3f}",
            f"ANTENNA {a}\tFREQUENCY\t{2115 + 10 * a:.3f}",
            f"ANTENNA {a}\tPOWER\t40.000 dBm Output",
            f"ANTENNA {a}\tANTENNATYPE\tISO",
        ]
    lines += [
        f"LOWER_LEFT\t{E0 - RES / 2:.8f} {N0 - RES / 2:.8f}",
        f"UPPER_RIGHT\t{E0 + (NX - 0.5) * RES:.8f} {N0 + (NY - 0.5) * RES:.8f}",
        "HEIGHT\t100.000",
        "TIME_STEP\t0.000",
        f"RESOLUTION\t{RES:.8f}",
        "",
        "BEGIN_DATA",
    ]
    for i in range(NX):
        for j in range(NY):
            value = "N.C." if (i + 2 * j) % 9 == 0 else f"{rng.uniform(-16, 17):.4f}"
            lines.append(f"{E0 + i * RES:.5f} {N0 + j * RES:.5f} {value}")
    lines.append("END_DATA")
    return "\n".join(lines) + "\n"


def naive_map(text: str) -> np.ndarray:
    """The values a plain reading of the data lines puts on the original grid (valid only for a file the reader
    accepted: then every data line has three fields on the grid)."""
    out = np.full((NX, NY), -999.0)
    lines = text.split("\n")
    begin = next(k for k, line in enumerate(lines) if line.strip() == "BEGIN_DATA")
    for line in lines[begin + 1 :]:
        if line.strip() == "END_DATA":
            break
        if not line.split():
            continue
        e, n, value = line.split()
        i, j = round((float(e) - E0) / RES), round((float(n) - N0) / RES)
        out[i, j] = np.nan if value == "N.C." else float(value)
    return out


def mutate(raw: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    kind = str(rng.choice(["truncate", "flip_bit", "replace_byte", "swap_header", "delete", "duplicate", "swap_lines"]))
    data = bytearray(raw)
    if kind == "truncate":
        return kind, bytes(data[: int(rng.integers(0, len(data)))])
    if kind == "flip_bit":
        k = int(rng.integers(len(data)))
        data[k] ^= 1 << int(rng.integers(8))
        return kind, bytes(data)
    if kind == "replace_byte":
        k = int(rng.integers(len(data)))
        data[k] = int(rng.choice(list(b"0123456789.-+eE \tN\n\x00")))
        return kind, bytes(data)
    lines = raw.decode().split("\n")
    if kind == "swap_header":
        # The values of two header keys change places (RESOLUTION <-> HEIGHT, LOWER_LEFT <-> UPPER_RIGHT, ...).
        rows = [k for k, line in enumerate(lines) if line.split("\t")[0] in HEADER_KEYS]
        a, b = rng.choice(rows, size=2, replace=False)
        key_a, value_a = lines[a].split("\t", 1)
        key_b, value_b = lines[b].split("\t", 1)
        lines[a], lines[b] = f"{key_a}\t{value_b}", f"{key_b}\t{value_a}"
    else:
        k = int(rng.integers(len(lines) - 1))
        if kind == "delete":
            del lines[k]
        elif kind == "duplicate":
            lines.insert(k, lines[k])
        else:
            m = int(rng.integers(len(lines) - 1))
            lines[k], lines[m] = lines[m], lines[k]
    return kind, "\n".join(lines).encode()


def check_error(exc: WinPropFormatError, raw: bytes) -> None:
    lines = raw.split(b"\n")
    if raw.endswith(b"\n"):
        lines = lines[:-1]
    assert 1 <= exc.lineno <= max(len(lines), 1), (exc.lineno, len(lines), str(exc))
    assert re.search(rf": lines? {exc.lineno}\b", str(exc)), str(exc)
    if exc.line is not None:
        assert exc.line == lines[exc.lineno - 1].decode("ascii").rstrip("\r").strip(), (exc.line, str(exc))
        assert str(exc).endswith(repr(exc.line))


def check_map(path: Path, raw: bytes) -> None:
    radio = read_winprop(path)
    assert radio.shape == (NX, NY)
    assert radio.resolution_m == pytest.approx(RES, rel=1e-4)
    assert radio.utm_origin_m == pytest.approx((E0, N0), abs=RES * 1e-3)
    expected = naive_map(raw.decode("ascii"))
    np.testing.assert_array_equal(radio.sinr_db, expected)
    assert not np.any(np.isinf(radio.sinr_db))
    for bs in radio.base_stations:
        assert np.isfinite([bs.x_m, bs.y_m, bs.height_m]).all()


def read_and_check(path: Path, mutated: bytes) -> str:
    try:
        check_map(path, mutated)
    except WinPropFormatError as exc:
        check_error(exc, mutated)
        return "error"
    return "map"


def test_mutated_files_give_a_named_line_or_a_correct_map(tmp_path: Path) -> None:
    raw = original_text().encode()
    path = tmp_path / "map.txt"
    path.write_bytes(raw)
    np.testing.assert_array_equal(read_winprop(path).sinr_db, naive_map(raw.decode()))  # the oracle agrees

    rng = np.random.default_rng(2026)
    outcomes: dict[str, int] = {}
    for _ in range(1500):
        kind, mutated = mutate(raw, rng)
        path.write_bytes(mutated)
        try:
            outcome = read_and_check(path, mutated)
        except Exception as exc:  # any other exception, or a failed check: show the mutation
            raise AssertionError(f"mutation {kind}: {exc!r}\n{mutated.decode('latin-1')}") from exc
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
    # Both branches are exercised: most mutations break the file, some leave a readable map.
    assert outcomes.get("error", 0) > 500 and outcomes.get("map", 0) > 100, outcomes
