"""Instance generators refuse, at once and by name, what they used to hang on, crash on or clamp silently."""

from __future__ import annotations

import time

import pytest

from uamfleet.config import ConfigError
from uamfleet.instances import make_fleet_instance, make_instance


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"num_requests": 10**7}, r"num_requests=10000000 is too large: at most 1024"),  # hung drawing requests
        ({"num_requests": 2.5}, r"num_requests=2.5 must be a whole number"),  # a NumPy traceback
        ({"num_taxis": 0}, r"num_taxis=0 must be an integer in \[1, 1024\]"),
        ({"seed": True}, r"seed=True is a bool"),  # accepted as seed 1
        ({"seed": -1}, r"seed=-1 must be an integer"),
        ({"arrival_window_s": 0}, r"arrival_window_s=0 must be a positive number"),  # clamped to one slot
        ({"arrival_window_s": -5}, r"arrival_window_s=-5 must be a positive number"),
        ({"arrival_window_s": float("nan")}, r"arrival_window_s=nan must be a finite number"),
        ({"num_vertiports": 1}, r"num_vertiports=1 must be 0"),
        ({"num_vertiports": -2}, r"num_vertiports=-2 must be an integer >= 0"),
        ({"family": "paris"}, r"unknown instance family 'paris'"),
    ],
)
def test_bad_fleet_instance_arguments_are_named(overrides, message):
    args = {"family": "berlin", "seed": 0, **overrides}
    start = time.perf_counter()
    with pytest.raises(ValueError, match=message):
        make_fleet_instance(**args)
    assert time.perf_counter() - start < 1.0


def test_a_bool_seed_is_not_an_instance():
    with pytest.raises(ConfigError, match=r"seed=True is a bool"):
        make_instance("berlin", True)


def test_valid_arguments_still_draw_the_same_instance():
    one, again = make_fleet_instance("berlin", 0, 2, 4), make_fleet_instance("berlin", 0.0, 2, 4.0)
    assert one.scenario == "berlin_fleet2x4_seed0" and one.requests == again.requests and one.starts_m == again.starts_m
