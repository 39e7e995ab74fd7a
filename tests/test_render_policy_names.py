"""uamfleet render: ``--policy`` takes the registry's grammar (a search over a learned base flies and is drawn), and
a name it cannot read is one line and exit 2 before anything is written."""

from __future__ import annotations

import dataclasses

from pathlib import Path

import uamfleet
from uamfleet.cli import render
from uamfleet.metrics import episode_metrics


def test_a_recorded_learned_name_flies_and_is_drawn(tmp_path: Path, capsys) -> None:
    out = tmp_path / "stops.html"
    assert render.cli(["--policy", "learned:berlin_stops", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    # learned:<stem> reads every request of the world: berlin_p4's 4 rows for its one taxi
    cfg = uamfleet.make_config("berlin_p4")
    stops = uamfleet.pretrained("berlin_stops")
    assert stops.spec is not None and stops.spec.slots_per_taxi == 6
    own = stops.reading(dataclasses.replace(stops.spec, slots_per_taxi=4)).fly(cfg, seed=0)
    m = episode_metrics(own, cfg.radio, threshold_db=cfg.sinr_min_db)
    assert "berlin_p4 · learned:berlin_stops · 1 taxi · γ_T = -3 dB" in printed
    assert f": {own.num_steps} steps (all delivered), 4/4 delivered, TD {m.td_m:.0f} m" in printed, printed
    assert out.is_file() and out.stat().st_size > 100_000 and "wrote html" in printed


def test_an_unknown_policy_is_one_line_and_exit_2_and_writes_nothing(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sub" / "x.html"
    assert render.cli(["--policy", "guided(lerned)", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured.err
    assert captured.err.startswith("uamfleet-render: error: ") and "unknown policy 'lerned'" in captured.err
    assert not out.parent.exists()
