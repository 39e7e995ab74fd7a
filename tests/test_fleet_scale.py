"""benchmarks/fleet_scale.py: a bad setting is refused before anything flies, and a row's figures add up."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "benchmarks/fleet_scale.py", *argv], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)  # fmt: skip


def test_more_requests_than_passenger_slots_are_refused_before_anything_flies(tmp_path: Path) -> None:
    out = tmp_path / "never.csv"
    done = _run("--settings", "2x4", "64x2000", "--methods", "greedy", "--out-csv", str(out))
    assert done.returncode != 0 and "num_requests=2000 is too large: at most 1024" in done.stderr
    assert not out.exists()


def test_one_episode_per_method_and_its_figures_add_up(tmp_path: Path) -> None:
    out = tmp_path / "scale.csv"
    done = _run("--settings", "2x4", "--arrival-window-s", "60", "--methods", "greedy", "--out-csv", str(out))
    assert done.returncode == 0, done.stderr
    (row,) = list(csv.DictReader(out.open()))
    assert (row["method"], row["taxis"], row["requests"]) == ("greedy", "2", "4")
    assert float(row["service_pct"]) == 100.0 and row["separation_violations"] == "0"
    assert float(row["wall_s"]) == pytest.approx(float(row["fields_s"]) + float(row["fly_s"]))
    assert float(row["s_per_step"]) == pytest.approx(float(row["fly_s"]) / float(row["steps"]))
    assert float(row["peak_rss_mb"]) > 50.0  # a Python process with numpy and the env: tens of MB at least


@pytest.mark.parametrize(
    ("method", "message"),
    [
        ("bogus", "unknown policy 'bogus'"),
        ("batch_assignment:heading=sideways", "heading='sideways': choose one of field, table, onward"),
        ("replan", "--methods 'replan' is a planner; name a fleet dispatcher"),
    ],
)
def test_a_method_that_is_no_fleet_dispatcher_is_refused_in_the_registrys_words(
    method: str, message: str, tmp_path: Path
) -> None:
    out = tmp_path / "never.csv"
    done = _run("--settings", "2x4", "--methods", method, "--out-csv", str(out))
    assert done.returncode != 0 and message in done.stderr
    assert not out.exists()
