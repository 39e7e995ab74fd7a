"""The paper-table command end to end (quick mode): CSV, Markdown section, figures, and a learned policy's row;
without --out-md it writes no Markdown file and points to ``uamfleet docs-tables``."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from uamfleet.cli.paper_table import Args, main
from uamfleet.rl.trainer import train
from tests.conftest import tiny_train_args


def test_quick_table_with_a_checkpoint(tmp_path: Path) -> None:
    result = train(tiny_train_args(tmp_path, sinr_min_db=-3.0, variant="full"))
    md = tmp_path / "results.md"
    md.write_text("# Results\n\nhand-written text stays\n")
    main(Args(quick=True, out_md=md, out_csv=tmp_path / "t.csv", figures=tmp_path / "fig",
              checkpoints=(result.run_dir / "best.pt",)))  # fmt: skip
    rows = list(csv.DictReader((tmp_path / "t.csv").open()))
    ours = {r["method"]: r for r in rows if r["source"] == "ours"}
    assert set(ours) == {"cptsp", "pdpcc", "raster_replan", "raster_opt", "straight", "msha-full"}
    assert float(ours["raster_opt"]["pr_pct"]) == 100.0 and float(ours["raster_opt"]["td_m"]) <= float(
        ours["cptsp"]["td_m"]
    )
    assert {r["method"] for r in rows if r["source"] == "paper"} >= {"CPTSP", "PDPCC", "MSHA-RL"}
    text = md.read_text()
    assert "hand-written text stays" in text and "<!-- paper_table:begin -->" in text and "msha-full" in text
    assert (tmp_path / "fig" / "routes_berlin_p4_-3dB.png").stat().st_size > 10_000


def test_default_run_writes_no_markdown_and_points_to_docs_tables(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # In a checkout's root the old default (--out-md docs/results.md) would write into the generated page.
    (tmp_path / "docs").mkdir()
    monkeypatch.chdir(tmp_path)
    rows = main(Args(quick=True, out_csv=tmp_path / "t.csv", figures=tmp_path / "fig"))
    assert not list(tmp_path.rglob("*.md"))
    assert len(list(csv.DictReader((tmp_path / "t.csv").open()))) == len(rows) > 0
    out = capsys.readouterr().out
    assert "| γ_T dB | method | source |" in out and "| raster_opt | ours |" in out  # the table, printed
    assert [line for line in out.splitlines() if "uamfleet docs-tables" in line] == [
        "run `uamfleet docs-tables` to refresh the results pages (docs/results.md, README.md) from the CSVs"
    ]
