"""Radio maps: expected-SINR rasters in an explicit world frame, their I/O, and the 3GPP channel model."""

from uamfleet.radio.channel_3gpp import expected_sinr_db, expected_sinr_map_3gpp
from uamfleet.radio.packaged import DETROIT_BELOW_FLOOR_DB, RADIO_MAPS, load_radio_map
from uamfleet.radio.radio_map import BaseStation, BlockMap, RadioMap
from uamfleet.radio.winprop import WinPropFormatError, read_winprop

__all__ = [
    "DETROIT_BELOW_FLOOR_DB",
    "RADIO_MAPS",
    "BaseStation",
    "BlockMap",
    "RadioMap",
    "WinPropFormatError",
    "expected_sinr_db",
    "expected_sinr_map_3gpp",
    "load_radio_map",
    "read_winprop",
]
