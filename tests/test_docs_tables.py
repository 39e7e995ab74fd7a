"""The results tables of the documentation (``uamfleet docs-tables``): the committed pages are exactly what their
CSVs give, a tiny table computed by hand comes out as computed, the marker writer keeps everything outside its
markers, and bad definitions fail in one line."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from uamfleet.cli.docs_tables import TABLES, TablesError, cli, fill, generate, load_tables, render, write_table

ROOT = Path(__file__).resolve().parents[1]


def test_the_committed_pages_are_what_their_csvs_give(tmp_path: Path) -> None:
    _, pages = load_tables(ROOT / TABLES)
    assert "docs/results.md" in pages
    generate(ROOT, out_dir=tmp_path)
    for page in pages:
        committed = (ROOT / page).read_bytes()
        assert (tmp_path / page).read_bytes() == committed, f"{page} differs from its CSVs: run `uamfleet docs-tables`"
    for page in ("docs/results.md", "docs/benchmarks.md"):
        assert page in pages and (ROOT / page).read_bytes().count(b"<!-- docs-tables:begin ") >= 1, page


def test_the_readme_table_is_the_headline() -> None:
    # README.md is one of the pages (checked above) and holds the `readme` table between its markers: search at
    # decision time against `replan` and `best_known` on the Berlin test set.
    tables, pages = load_tables(ROOT / TABLES)
    assert "README.md" in pages
    assert tables["readme"].parts == ("search_berlin_test",)
    table = render(tables["search_berlin_test"], ROOT)
    assert "| `replan` (online, beam 64) | 100 | 9,793.0 | 1.000 | 1.124 |" in table
    assert "| `best_known` (clairvoyant) | 100 | 8,813.0 | 0.900 | 1.000 |" in table


TINY_CSV = """set,instance,method,pr_pct,td_m,awt_s
s,1,best,100.0,10.0,5.0
s,1,a,100.0,12.0,6.0
s,1,b,50.0,30.0,nan
s,2,best,100.0,20.0,7.0
s,2,a,100.0,30.0,8.0
s,2,b,100.0,22.0,9.0
s,3,best,100.0,30.0,1.0
s,3,a,100.0,30.0,2.0
s,3,b,100.0,33.0,3.0
other,1,a,100.0,999.0,999.0
"""

TINY_TOML = """pages = ["page.md"]

[tables.tiny]
csv = "tiny.csv"
command = "make tiny.csv"
test = "--rows 1"
where = "set == 's' and method != 'best'"
group_by = ["method"]
order = ["b", "a"]
refs.best = { where = "method == 'best'", on = ["instance"] }
labels.a = "method A"
columns = [
  { title = "method", value = "method" },
  { title = "n", value = "1", agg = "count", format = "d" },
  { title = "all delivered %", value = "pr_pct >= 100", agg = "mean", scale = 100, format = ".1f" },
  { title = "TD m", value = "td_m", agg = "mean_ci", format = ",.2f" },
  { title = "mean of ratios", value = "td_m / best_td_m", when = "pr_pct >= 100", agg = "mean", format = ".4f" },
  { title = "ratio of means", value = "td_m", over = "best_td_m", agg = "mean", format = ".4f" },
  { title = "AWT s", value = "awt_s", agg = "median", format = ".1f" },
  { title = "worst", value = "td_m - best_td_m", agg = "max", format = "+.0f" },
]
note = "A note."

[tables.pivoted]
csv = "tiny.csv"
where = "set == 's'"
group_by = ["instance"]
columns = [{ title = "instance", value = "instance", format = ".0f" }]
pivot = "method"
pivot_order = ["best", "a"]
cell = { value = "td_m", format = ".0f" }

[tables.both]
parts = ["pivoted", "tiny"]
"""


def tiny_root(tmp_path: Path, toml: str = TINY_TOML, page: str = "") -> Path:
    (tmp_path / "docs" / "results").mkdir(parents=True)
    (tmp_path / TABLES).write_text(toml, encoding="utf-8")
    (tmp_path / "tiny.csv").write_text(TINY_CSV, encoding="utf-8")
    (tmp_path / "page.md").write_text(page, encoding="utf-8")
    return tmp_path


def test_a_tiny_table_is_the_one_computed_by_hand(tmp_path: Path) -> None:
    root = tiny_root(tmp_path)
    tables, pages = load_tables(root / TABLES)
    assert pages == ["page.md"]
    # b: TDs 30, 22, 33 (instance 1 delivered half), bests 10, 20, 30. Mean 85/3 = 28.33; deviations 5/3, -19/3,
    # 14/3 -> squares 25/9 + 361/9 + 196/9 = 582/9, / 2 (ddof 1) = 291/9, sd 5.686; half = 1.96 * 5.686 / sqrt(3)
    # = 6.43. Mean of ratios over the delivered instances 2 and 3: (1.1 + 1.1) / 2; ratio of means (85/3) / 20;
    # AWT median of 9 and 3 (the NaN skipped) = 6; worst 30 - 10 = +20.
    half_b = 1.96 * math.sqrt(291 / 9) / math.sqrt(3)
    assert f"{half_b:.2f}" == "6.43"
    # a: TDs 12, 30, 30 over bests 10, 20, 30: mean 24, deviations -12, 6, 6 -> sd sqrt(216 / 2) = sqrt(108);
    # half = 1.96 * sqrt(108) / sqrt(3) = 1.96 * 6 = 11.76; ratios 1.2, 1.5, 1.0 -> 1.2333; ratio of means 72 / 60;
    # AWT median of 6, 8, 2 = 6; worst 30 - 20 = +10.
    assert render(tables["tiny"], root) == "\n".join([
        "<!-- test: --rows 1 -->",  # how tests/test_docs.py runs the command
        "```bash",
        "make tiny.csv",
        "```",
        "",
        "| method | n | all delivered % | TD m | mean of ratios | ratio of means | AWT s | worst |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
        "| b | 3 | 66.7 | 28.33 ± 6.43 | 1.1000 | 1.4167 | 6.0 | +20 |",
        "| method A | 3 | 100.0 | 24.00 ± 11.76 | 1.2333 | 1.2000 | 6.0 | +10 |",
        "",
        "A note.",
    ])  # fmt: skip
    pivoted = "\n".join([
        "| instance | best | a |",
        "|---:|---:|---:|",
        "| 1 | 10 | 12 |",
        "| 2 | 20 | 30 |",
        "| 3 | 30 | 30 |",
    ])  # fmt: skip
    assert render(tables["pivoted"], root) == pivoted
    assert render(tables["both"], root, tables) == pivoted + "\n\n" + render(tables["tiny"], root)
    as_written = render(replace(tables["tiny"], test=""), root)  # test = "": the command runs as written
    assert as_written.startswith("<!-- test: -->\n```bash\nmake tiny.csv\n```\n")


def test_the_marker_writer_replaces_only_the_text_between_its_markers(tmp_path: Path) -> None:
    page = "\n".join([
        "# A page",
        "",
        "Text before.",
        "<!-- docs-tables:begin pivoted -->",
        "an old table",
        "<!-- docs-tables:end pivoted -->",
        "Text after, with <!-- docs-tables:begin pivoted --> inside a line (not a marker).",
        "",
    ])  # fmt: skip
    root = tiny_root(tmp_path, page=page)
    tables, _ = load_tables(root / TABLES)
    write_table(root / "page.md", "pivoted", tables, root)
    written = (root / "page.md").read_text(encoding="utf-8")
    head, tail = page.split("an old table\n")
    assert written == head + render(tables["pivoted"], root) + "\n" + tail
    write_table(root / "page.md", "pivoted", tables, root)
    assert (root / "page.md").read_text(encoding="utf-8") == written  # filling again changes nothing
    with pytest.raises(TablesError, match="has no line '<!-- docs-tables:begin tiny -->'"):
        write_table(root / "page.md", "tiny", tables, root)


@pytest.mark.parametrize(
    ("page", "message"),
    [
        ("<!-- docs-tables:begin tiny -->\nno end\n", "has no line '<!-- docs-tables:end tiny -->'"),
        ("<!-- docs-tables:begin nothing -->\n<!-- docs-tables:end nothing -->\n", "no table 'nothing'"),
        ("<!-- docs-tables:end tiny -->\n", "an end marker of 'tiny' without its begin line"),
    ],
)
def test_broken_markers_fail_naming_the_line(tmp_path: Path, page: str, message: str) -> None:
    root = tiny_root(tmp_path)
    tables, _ = load_tables(root / TABLES)
    with pytest.raises(TablesError, match=message):
        fill(page, tables, root, "page.md")


def test_the_command_checks_writes_and_names_a_stale_page(tmp_path: Path, capsys) -> None:
    page = "x\n<!-- docs-tables:begin pivoted -->\n<!-- docs-tables:end pivoted -->\n"
    root = tiny_root(tmp_path, page=page)
    assert cli(["--root", str(root), "--check"]) == 1
    assert "page.md differs from its CSVs" in capsys.readouterr().err
    out_dir = tmp_path / "out"
    assert cli(["--root", str(root), "--out-dir", str(out_dir)]) == 0
    assert (root / "page.md").read_text(encoding="utf-8") == page  # --out-dir leaves the page alone
    assert cli(["--root", str(root)]) == 0
    assert (root / "page.md").read_text(encoding="utf-8") == (out_dir / "page.md").read_text(encoding="utf-8")
    assert cli(["--root", str(root), "--check"]) == 0


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("where = \"set == 's' and method != 'best'\"", "where = \"__import__('os')\""), "uses Call"),
        (('agg = "median"', 'agg = "mode"'), "agg 'mode' is not one of first, mean"),
        (('csv = "tiny.csv"\ncommand', 'csv = "missing.csv"\ncommand'), "missing.csv: no such CSV"),
        (('value = "awt_s"', 'value = "awt"'), "name 'awt' is not defined"),
        (('format = "+.0f"', 'format = "q"'), "format 'q' of the column 'worst' is no number format"),
        (('parts = ["pivoted", "tiny"]', 'parts = ["pivoted", "nope"]'), "'nope' is not a table"),
        # a command comes with the words that size it in tests/test_docs.py, and those words with a command
        (('test = "--rows 1"\n', ""), 'tables.tiny: a command needs test = "<sizes'),
        (('pivot = "method"', 'test = "slow"\npivot = "method"'), 'tables.pivoted: a command needs test = "<sizes'),
        (('test = "--rows 1"', "test = 1"), 'tables.tiny: a command needs test = "<sizes'),
    ],
)
def test_a_bad_definition_is_one_line_naming_it(tmp_path: Path, capsys, change: tuple[str, str], message: str) -> None:
    assert change[0] in TINY_TOML
    page = "<!-- docs-tables:begin both -->\n<!-- docs-tables:end both -->\n"
    root = tiny_root(tmp_path, toml=TINY_TOML.replace(change[0], change[1], 1), page=page)
    assert cli(["--root", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("uamfleet docs-tables: error: ") and message in err and err.count("\n") == 1, err
    assert (root / "page.md").read_text(encoding="utf-8") == page  # nothing written
