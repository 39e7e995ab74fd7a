"""A TR 36.777 UMi-AV expected-SINR map (the model of the packaged ``detroit_3gpp``) at Berlin's scale and GBS
density, small enough to label with the step-level search: 2 km square, 10 m cells, 9 GBS on a 750 m grid.

    PYTHONPATH=$PWD python reports/2026-12-04-mix3gpp/make_map.py
"""

from __future__ import annotations

from pathlib import Path

from uamfleet.radio.channel_3gpp import expected_sinr_map_3gpp
from uamfleet.radio.packaged import DETROIT_3GPP_NOISE_DBM, umi_av_stations
from uamfleet.radio.raytrace import save_radio_map_npz

SIDE_M, SPACING_M = 2000.0, 750.0
sites = [(250.0 + i * SPACING_M, 250.0 + j * SPACING_M) for i in range(3) for j in range(3)]
stations = umi_av_stations(sites)  # detroit_3gpp's masts (20 m), power (40 dBm) and loading
radio = expected_sinr_map_3gpp(
    stations,
    side_m=SIDE_M,
    resolution_m=10.0,
    altitude_m=100.0,
    carrier_ghz=2.0,
    noise_dbm=DETROIT_3GPP_NOISE_DBM,
    name="umi_av_2km",
    source="SYNTHETIC: 3GPP TR 36.777 UMi-AV expected SINR (paper Eq. 6), 9 GBS on a 750 m grid over 2 km; "
    "reports/2026-12-04-mix3gpp/make_map.py",
)
print(save_radio_map_npz(radio, Path(__file__).with_name("umi_av_2km.npz")))
