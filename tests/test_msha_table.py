"""The MSHA results command: training-cost bookkeeping by hand, and the tables from a tiny trained run."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from uamfleet.cli.msha_table import Args, experiments, first_reaching, main
from uamfleet.rl.trainer import TrainArgs, train


def test_first_reaching_picks_the_first_full_delivery_within_the_limit():
    rows = [
        {"global_step": 100.0, "wall_s": 1.0},  # no evaluation in this iteration
        {"global_step": 200.0, "wall_s": 2.0, "eval/pr_pct": 75.0, "eval/td_m": 20000.0},
        {"global_step": 300.0, "wall_s": 3.0, "eval/pr_pct": 100.0, "eval/td_m": 9000.0},
        {"global_step": 400.0, "wall_s": 4.0, "eval/pr_pct": 100.0, "eval/td_m": 5200.0},
    ]
    assert first_reaching(rows, math.inf) == (300.0, 3.0)
    assert first_reaching(rows, 6200.0) == (400.0, 4.0)
    assert all(math.isnan(v) for v in first_reaching(rows, 5000.0))


def test_experiment_grid_names_and_budgets():
    grid = experiments((1, 2), "de_msfea", steps=1000, detroit_steps=2000)
    names = [e.name for e in grid]
    assert len(names) == len(set(names)) == 2 * (5 + 1 + 3)  # 5 Berlin thresholds + Detroit, 3 other variants
    assert "berlin_p4_-3dB_de_msfea_s2" in names and "detroit_p5_-17dB_de_msfea_s1" in names
    assert {e.variant for e in grid if e.group == "ablation"} == {"le", "de", "full"}
    assert {e.total_timesteps for e in grid if e.scenario == "detroit_p5"} == {2000}


def _tiny_le_run(run_dir: Path, name: str) -> None:
    """One short PPO iteration of the linear-encoder variant on Berlin P4 at -3 dB, as the table's run ``name``."""
    train(TrainArgs.from_flat(dict(
        sinr_min_db=-3.0, variant="le", total_timesteps=64, num_envs=2, num_steps=32, num_minibatches=1,
        update_epochs=1, run_dir=run_dir, run_name=name, progress=False, tensorboard=False, threads=1,
        time_limit_steps=40, eval_every=1,
    )))  # fmt: skip


def test_tables_from_a_tiny_run(tmp_path: Path) -> None:
    name = "berlin_p4_-3dB_le_s1"
    _tiny_le_run(tmp_path, name)
    md = tmp_path / "results.md"
    md.write_text("# Results\n\nhand-written text stays\n")
    rows = main(Args(run_dir=tmp_path, only=(name,), seeds=(1,), train=False, feasibility="endpoint_block",
                     out_md=md, out_csv=tmp_path / "t.csv"))  # fmt: skip
    assert [r["run"] for r in rows] == [name]
    saved = list(csv.DictReader((tmp_path / "t.csv").open()))
    assert saved[0]["variant"] == "le" and float(saved[0]["opt_td_m"]) == 5100.0  # raster_opt at -3 dB, endpoint rule
    assert float(saved[0]["total_steps"]) == 64.0
    text = md.read_text()
    assert "hand-written text stays" in text and "<!-- msha_table:begin -->" in text
    assert "| 1 | le | 1 |" in text and "raster_opt (ours) | 100 | 5,100 |" in text
    assert "**MSHA-PPO le" not in text  # an ablation run is not a row of the main table


def test_filters_leave_out_the_ablation_and_other_scenarios(tmp_path: Path) -> None:
    # With the filters nothing is chosen, so nothing is trained or written and the command says so (exit 2).
    for kwargs in ({"ablation": False, "only": ("_le_",)}, {"scenarios": ("detroit_p5",), "only": ("berlin",)}):
        with pytest.raises(ValueError, match="no run selected"):
            main(Args(run_dir=tmp_path, train=True, out_md=tmp_path / "r.md", out_csv=tmp_path / "t.csv", **kwargs))
        assert not any(tmp_path.glob("*.log"))  # nothing was trained


def test_default_run_writes_no_markdown_and_points_to_docs_tables(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    name = "berlin_p4_-3dB_le_s1"
    _tiny_le_run(tmp_path, name)
    (tmp_path / "docs").mkdir()
    monkeypatch.chdir(tmp_path)  # in a checkout's root the old default (--out-md docs/results.md) wrote the page
    capsys.readouterr()
    rows = main(Args(run_dir=tmp_path, only=(name,), seeds=(1,), train=False, feasibility="endpoint_block",
                     out_csv=tmp_path / "t.csv"))  # fmt: skip
    assert [r["run"] for r in rows] == [name]
    assert not list(tmp_path.rglob("*.md"))
    assert [r["run"] for r in csv.DictReader((tmp_path / "t.csv").open())] == [name]
    out = capsys.readouterr().out
    assert "| 1 | le | 1 |" in out and "raster_opt (ours) | 100 | 5,100 |" in out  # the tables, printed
    assert [line for line in out.splitlines() if "uamfleet docs-tables" in line] == [
        "run `uamfleet docs-tables` to refresh the results pages (docs/results.md, README.md) from the CSVs"
    ]
