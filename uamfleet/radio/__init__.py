"""Radio maps: expected-SINR rasters in an explicit world frame, their I/O, the 3GPP channel model, and maps
ray-traced with Sionna RT (optional extra ``rt``; imported only when a map is ray-traced)."""

from uamfleet.radio.channel_3gpp import expected_sinr_db, expected_sinr_map_3gpp
from uamfleet.radio.packaged import DETROIT_BELOW_FLOOR_DB, RADIO_MAPS, load_radio_map
from uamfleet.radio.radio_map import BaseStation, BlockMap, RadioMap
from uamfleet.radio.raytrace import RayTracingParams, ray_traced_radio_map, read_radio_map_npz, save_radio_map_npz
from uamfleet.radio.winprop import WinPropFormatError, read_winprop

__all__ = [
    "DETROIT_BELOW_FLOOR_DB",
    "RADIO_MAPS",
    "BaseStation",
    "BlockMap",
    "RadioMap",
    "RayTracingParams",
    "WinPropFormatError",
    "expected_sinr_db",
    "expected_sinr_map_3gpp",
    "load_radio_map",
    "ray_traced_radio_map",
    "read_radio_map_npz",
    "read_winprop",
    "save_radio_map_npz",
]
