"""Regenerate the packaged radio data in ``uamfleet/data/`` from the shared source files.

    python -m uamfleet.radio._build_packaged [SOURCE_DIR]      # default /work/shared/data

Writes ``berlin_sinr_100m.npz`` (from ``berlin/berlin_UAM_SNIR_100.txt``), ``LICENSE.berlin`` (the upstream
MIT licence with a header saying what it covers) and ``detroit_block_sinr_estimate.csv`` (copied verbatim).
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np

from uamfleet.radio.packaged import BERLIN_LICENSE, BERLIN_NC, BERLIN_NPZ, DATA_DIR, DETROIT_CSV
from uamfleet.radio.winprop import read_winprop

DEFAULT_SOURCE = Path("/work/shared/data")
BERLIN_TXT = "berlin_UAM_SNIR_100.txt"


def build(source: Path = DEFAULT_SOURCE, out: Path = DATA_DIR) -> list[Path]:
    """Write the packaged files into ``out``; returns their paths."""
    out.mkdir(parents=True, exist_ok=True)
    radio = read_winprop(source / "berlin" / BERLIN_TXT)
    sinr = radio.sinr_db
    scaled = np.rint(np.where(np.isnan(sinr), 0.0, sinr) * 1e4)
    if not np.array_equal(scaled[~np.isnan(sinr)] / 1e4, sinr[~np.isnan(sinr)]):
        raise ValueError(f"{BERLIN_TXT} has values with more than 4 decimals; int32 1e-4 dB storage would be lossy")
    stations = radio.base_stations
    assert radio.utm_origin_m is not None
    npz = out / BERLIN_NPZ
    np.savez_compressed(
        npz,
        sinr_1e4_db=np.where(np.isnan(sinr), BERLIN_NC, scaled).astype(np.int32),  # [ix, iy], 1e-4 dB
        resolution_m=np.float64(radio.resolution_m),
        altitude_m=np.float64(radio.altitude_m),
        utm_origin_m=np.array(radio.utm_origin_m),  # UTM 33N (E, N) of world (0, 0)
        bs_xyh_power_freq=np.array([[b.x_m, b.y_m, b.height_m, b.power_dbm, b.frequency_mhz] for b in stations]),
        bs_name=np.array([b.name for b in stations]),
        source=np.array(
            f"WinProp ASCII {BERLIN_TXT} from Traffic-Alpha/UAM-Path-Planning (MIT; uamfleet/data/{BERLIN_LICENSE})"
        ),
    )
    licence = out / BERLIN_LICENSE
    upstream = (source / "berlin" / "LICENSE.upstream").read_text()
    licence.write_text(
        f"Covers uamfleet/data/{BERLIN_NPZ}, a lossless re-encoding of {BERLIN_TXT} from "
        "https://github.com/Traffic-Alpha/UAM-Path-Planning; its licence follows.\n\n" + upstream
    )
    csv = out / DETROIT_CSV
    shutil.copyfile(source / "detroit" / DETROIT_CSV, csv)
    return [npz, licence, csv]


if __name__ == "__main__":
    for written in build(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_SOURCE):
        print(f"wrote {written} ({written.stat().st_size} bytes)")
