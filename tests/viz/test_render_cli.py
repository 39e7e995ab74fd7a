"""``python -m eval.render``: the page and the PNG figures of one flown episode."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from PIL import Image

from uamfleet.cli.render import Args, main
from tests.conftest import TINY_FLEET, tiny_train_args


def test_planner_on_berlin_p4_writes_page_and_figures(tmp_path: Path) -> None:
    out = tmp_path / "berlin.html"
    written = main(Args(scenario="berlin_p4", policy="raster_replan", out=out, png=True))
    assert written["html"] == out
    assert set(written) == {"html", "routes", "sinr"}
    for path in written.values():
        assert path.exists() and path.stat().st_size > 10_000, path
    html = out.read_text(encoding="utf-8")
    assert "berlin_p4 · raster_replan · 1 taxi · γ_T = -3 dB" in html
    assert not re.search(r"<script[^>]*\bsrc\s*=", html)
    for name in ("routes", "sinr"):
        assert written[name].parent == tmp_path and written[name].name.startswith("berlin_")
        with Image.open(written[name]) as img:
            assert img.format == "PNG" and min(img.size) > 300


def test_fleet_with_the_greedy_dispatcher(tmp_path: Path) -> None:
    written = main(Args(scenario="berlin_random", policy="greedy", num_taxis=2, seed=3, out=tmp_path / "fleet.html"))
    html = written["html"].read_text(encoding="utf-8")
    assert set(written) == {"html"}
    assert "/meshcat/taxis/taxi_1" in html and "/meshcat/taxis/taxi_2" not in html


def test_planners_fly_one_taxi(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="single-taxi planner"):
        main(Args(scenario="berlin_p4", policy="raster_replan", num_taxis=2, out=tmp_path / "x.html"))
    with pytest.raises(ValueError, match="unknown --policy"):
        main(Args(policy="ppo", out=tmp_path / "x.html"))
    assert not (tmp_path / "x.html").exists()


def test_render_a_trained_checkpoint(tmp_path: Path) -> None:
    from uamfleet.rl.trainer import train

    result = train(tiny_train_args(tmp_path, **TINY_FLEET))
    written = main(Args(checkpoint=result.run_dir / "best.pt", out=tmp_path / "msha.html"))
    assert written["html"].stat().st_size > 100_000
