"""The set-up's warm-up flies every configuration it names (a renamed preset or option would break set-up)."""

from __future__ import annotations

import os

from uamfleet.warmup import warm


def test_warm_up_flies_its_configurations_and_leaves_the_table_cache_setting_alone() -> None:
    before = os.environ.get("UAMFLEET_CACHE")
    seconds = warm(steps=2, verbose=False)
    assert seconds > 0
    assert os.environ.get("UAMFLEET_CACHE") == before
