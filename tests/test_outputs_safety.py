"""Nothing is lost: every command refuses an empty selection and an existing result (without --overwrite) before
it writes anything, a long run keeps its partial rows beside the committed ones, paper-table keeps the rows it
did not produce, figures are byte-stable, and runs are never deleted by a command that was not told to.

The commands run in a scratch folder holding a copy of the repository's ``docs/results/`` and
``docs/results.md`` (their default outputs), so a command that wrote anything would show it here, never in the
repository."""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

from uamfleet.cli import benchmark, fleet_benchmark, msha_table, paper_table, quickstart, render, rollout
from uamfleet.cli import train as train_cli
from uamfleet.io import partial_path
from uamfleet.viz.figures import plot_connectivity

ROOT = Path(__file__).resolve().parents[1]
Cli = Callable[[Sequence[str] | None], int]


@pytest.fixture
def scratch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A current folder holding a copy of the committed results, as a user's checkout would."""
    (tmp_path / "docs").mkdir()
    shutil.copytree(ROOT / "docs" / "results", tmp_path / "docs" / "results")
    shutil.copy(ROOT / "docs" / "results.md", tmp_path / "docs" / "results.md")
    # a Markdown file holding the marked sections an --out-md of paper-table, msha-table, benchmark and fleet-bench
    # (re)writes
    sections = [f"<!-- {name}:{end} -->" for name in ("paper_table", "msha_table", "benchmark", "fleet")
                for end in ("begin", "end")]  # fmt: skip
    (tmp_path / "sections.md").write_text("\n".join(["# Results", *sections, ""]), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def exit_status(cli: Cli, argv: list[str]) -> int:
    try:
        return cli(argv)
    except SystemExit as done:
        return int(done.code or 0)


# (command, arguments selecting nothing, what the one-line error says)
EMPTY = [
    (benchmark.cli, ["--count", "0"], "no instance selected (--count 0 without --fixed)"),
    (benchmark.cli, ["--fixed", "--count", "0", "--fixed-thresholds", "99"], "match none of the fixed instances"),
    (benchmark.cli, ["--methods"], "--methods is empty and no --checkpoint is given"),
    (fleet_benchmark.cli, ["--count", "0"], "no episode selected"),
    (fleet_benchmark.cli, ["--settings"], "no episode selected (--settings (none)"),
    (fleet_benchmark.cli, ["--dispatchers"], "--dispatchers is empty and no --checkpoints"),
    (msha_table.cli, ["--only", "no-such-run", "--no-train"], "no run selected"),
    (msha_table.cli, ["--scenarios"], "no run selected"),
    (rollout.cli, ["--episodes", "0"], "--episodes 0"),
    (train_cli.cli, ["--total-timesteps", "0"], "--total-timesteps=0"),
    (quickstart.cli, ["--total-timesteps", "0"], "--total-timesteps=0"),
    # the committed results are there: without --overwrite they are refused before anything runs
    (paper_table.cli, [], "docs/results/paper_table.csv already holds results; pass --overwrite"),
    (
        paper_table.cli,
        ["--out-md", "sections.md"],
        "docs/results/paper_table.csv and the 'paper_table' section of sections.md already hold results",
    ),
    (
        benchmark.cli,
        ["--count", "1", "--out-csv", "docs/results/benchmark_fixed.csv"],
        "docs/results/benchmark_fixed.csv already holds results; pass --overwrite",
    ),
    (
        benchmark.cli,
        ["--count", "1", "--out-csv", "docs/results/benchmark_fixed.csv", "--out-md", "sections.md"],
        "docs/results/benchmark_fixed.csv and the 'benchmark' section of sections.md already hold results",
    ),
    (fleet_benchmark.cli, ["--count", "1"], "docs/results/fleet_benchmark.csv already holds results; pass --overwrite"),
    (
        fleet_benchmark.cli,
        ["--count", "1", "--out-md", "sections.md"],
        "docs/results/fleet_benchmark.csv and the 'fleet' section of sections.md already hold results",
    ),
    (msha_table.cli, ["--no-train"], "docs/results/msha_table.csv already holds results; pass --overwrite"),
    (
        msha_table.cli,
        ["--no-train", "--out-md", "sections.md"],
        "docs/results/msha_table.csv and the 'msha_table' section of sections.md already hold results",
    ),
    (render.cli, ["--out", "docs/results.md"], "docs/results.md already holds results; pass --overwrite"),
]


@pytest.mark.parametrize(("cli", "argv", "message"), EMPTY, ids=[f"{c[0].__module__} {c[1]}" for c in EMPTY])
def test_an_empty_selection_or_existing_result_changes_nothing(scratch, capsys, cli, argv, message):
    before = snapshot(scratch)
    assert exit_status(cli, argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert snapshot(scratch) == before  # not one byte written, no file added (not even a folder's file)


@pytest.mark.parametrize("jobs", ["0", "-1", "1000"])
def test_worker_counts_are_bounded(scratch, capsys, jobs):
    for cli, more in ((benchmark.cli, ["--count", "1"]), (fleet_benchmark.cli, ["--count", "1"]), (msha_table.cli, [])):
        assert exit_status(cli, ["--jobs", jobs, *more]) == 2
        assert f"--jobs {jobs}: give 1 ... " in capsys.readouterr().err


def test_partial_rows_go_beside_the_committed_csv(scratch, monkeypatch):
    """A run of three instances saves after each of the first two, to benchmark.partial.csv only; the committed
    CSV changes once, at the end, and the partial file is gone after a complete run."""
    out = Path("docs/results/benchmark_fixed.csv")
    committed = out.read_bytes()
    writes: list[tuple[Path, bool]] = []
    real = benchmark.write_csv_atomic

    def recording(path, rows, columns):
        writes.append((Path(path), out.read_bytes() == committed))
        return real(path, rows, columns)

    monkeypatch.setattr(benchmark, "write_csv_atomic", recording)
    rows = benchmark.main(benchmark.Args(count=3, methods=("straight",), jobs=1, out_csv=out, overwrite=True,
                                         out_md=Path("docs/results.md")))  # fmt: skip
    assert len(rows) == 3
    assert writes == [(partial_path(out), True), (partial_path(out), True), (out, True)]
    assert not partial_path(out).exists() and out.read_bytes() != committed
    assert "--overwrite" in Path("docs/results.md").read_text()  # the command printed above the table reproduces it


HINT = "run `uamfleet docs-tables` to refresh the results pages (docs/results.md, README.md) from the CSVs"


def test_a_default_benchmark_run_writes_the_csv_and_no_markdown(scratch, capsys):
    before = {p: b for p, b in snapshot(scratch).items() if p.endswith(".md")}
    rows = benchmark.main(benchmark.Args(count=1, methods=("straight",), jobs=1, out_csv=Path("out.csv")))
    assert len(rows) == 1 and len(Path("out.csv").read_text().splitlines()) == 2  # the header and the row
    assert {p: b for p, b in snapshot(scratch).items() if p.endswith(".md")} == before  # no Markdown written
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("| straight |") for line in lines)  # the table, printed
    assert lines[-2].startswith("wrote out.csv (") and lines[-1] == HINT


def test_a_default_fleet_benchmark_run_writes_the_csv_and_no_markdown(scratch, capsys):
    before = {p: b for p, b in snapshot(scratch).items() if p.endswith(".md")}
    rows = fleet_benchmark.main(fleet_benchmark.Args(settings=("2x6",), count=1, dispatchers=("greedy",), jobs=1,
                                                     out_csv=Path("out.csv")))  # fmt: skip
    assert len(rows) == 1 and len(Path("out.csv").read_text().splitlines()) == 2  # the header and the row
    assert {p: b for p, b in snapshot(scratch).items() if p.endswith(".md")} == before  # no Markdown written
    lines = capsys.readouterr().out.splitlines()
    assert any("| greedy |" in line for line in lines)  # the table, printed
    assert lines[-2].startswith("wrote out.csv (") and lines[-1] == HINT


def test_paper_table_keeps_the_rows_it_did_not_produce():
    def row(setting: str, threshold: float, method: str, source: str = "ours") -> dict[str, object]:
        return {"setting": setting, "threshold_db": threshold, "method": method, "source": source, "td_m": 1.0}

    berlin, detroit = paper_table.SETTINGS[0][3], paper_table.SETTINGS[1][3]
    earlier = [row(berlin, -7.0, "cptsp"), row(berlin, -7.0, "msha-de_msfea"), row(berlin, -3.0, "cptsp"),
               row(berlin, -3.0, "msha-de_msfea"), row(detroit, -17.0, "MSHA-RL", "paper")]  # fmt: skip
    now = [row(berlin, -3.0, "MSHA-RL", "paper"), {**row(berlin, -3.0, "cptsp"), "td_m": 2.0}]
    merged = paper_table.keep_other_rows(now, earlier)
    assert [(r["threshold_db"], r["method"], r["td_m"]) for r in merged] == [
        (-7.0, "cptsp", 1.0), (-7.0, "msha-de_msfea", 1.0),  # thresholds not flown now: kept as they were
        (-3.0, "MSHA-RL", 1.0), (-3.0, "cptsp", 2.0),  # this run's rows, the planner's replacing its earlier value
        (-3.0, "msha-de_msfea", 1.0),  # the learned row this run did not produce stays, after the planners
        (-17.0, "MSHA-RL", 1.0),
    ]  # fmt: skip


def test_a_quick_paper_table_rerun_keeps_the_learned_rows(scratch):
    before = (scratch / "docs/results/paper_table.csv").read_text()
    learned = [line for line in before.splitlines() if ",msha-" in line]
    assert learned, "the committed table has learned rows"
    paper_table.main(paper_table.Args(quick=True, figures=scratch / "fig", overwrite=True,
                                      out_md=Path("docs/results.md")))  # fmt: skip
    after = (scratch / "docs/results/paper_table.csv").read_text()
    assert [line for line in after.splitlines() if ",msha-" in line] == learned
    assert len(after.splitlines()) == len(before.splitlines())
    assert "msha-de_msfea" in (scratch / "docs/results.md").read_text()


def test_figures_are_byte_stable(tmp_path):
    paths = [tmp_path / "a.png", tmp_path / "b.png"]
    for path in paths:
        plot_connectivity([-7.0, -3.0], {"cptsp": [90.0, 80.0]}, "connectivity", path)
    assert paths[0].read_bytes() == paths[1].read_bytes()
    assert b"Software" not in paths[0].read_bytes() and b"matplotlib" not in paths[0].read_bytes()


def fake_run(folder: Path) -> dict[str, bytes]:
    folder.mkdir(parents=True)
    (folder / "progress.csv").write_text("iteration,global_step\n1,64\n")
    (folder / "last.pt").write_bytes(b"a run someone cares about")
    return snapshot(folder)


def test_quickstart_never_deletes_another_run(tmp_path, capsys):
    kept = fake_run(tmp_path / "mine")
    argv = ["--run-dir", str(tmp_path), "--run-name", "mine", "--total-timesteps", "2048", "--no-generalist"]
    assert exit_status(quickstart.cli, argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "already holds a run" in err and "--overwrite" in err
    assert snapshot(tmp_path / "mine") == kept


def test_train_checks_every_option_before_it_replaces_a_run(tmp_path, capsys):
    kept = fake_run(tmp_path / "r")
    base = ["--run-dir", str(tmp_path), "--run-name", "r", "--overwrite", "--scenario", "berlin_instances"]
    for bad, message in ((["--eval-instances", "20000"], "--eval-instances=20000 exceeds the 10,000 seeds"),
                         (["--thresholds", "-3", "-3"], "repeats [-3.0]")):  # fmt: skip
        assert exit_status(train_cli.cli, base + bad) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
        assert snapshot(tmp_path / "r") == kept


def test_the_run_exists_error_is_one_line(tmp_path, capsys):
    kept = fake_run(tmp_path / "r")
    argv = ["--run-dir", str(tmp_path), "--run-name", "r", "--total-timesteps", "64", "--num-envs", "1",
            "--num-steps", "64", "--no-progress", "--no-tensorboard"]  # fmt: skip
    assert exit_status(train_cli.cli, argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "already holds a run (progress.csv, last.pt)" in err and "Traceback" not in err
    assert snapshot(tmp_path / "r") == kept


def test_render_refuses_an_existing_page(tmp_path, capsys):
    page = tmp_path / "page.html"
    page.write_text("mine")
    figure = tmp_path / "new_routes.png"
    figure.write_text("mine too")
    assert exit_status(render.cli, ["--out", str(page)]) == 2
    assert exit_status(render.cli, ["--out", str(tmp_path / "new.html"), "--png"]) == 2
    assert "new_routes.png already holds results" in capsys.readouterr().err
    assert page.read_text() == "mine" and figure.read_text() == "mine too" and not (tmp_path / "new.html").exists()
    assert exit_status(render.cli, ["--out", str(page), "--overwrite", "--policy", "straight"]) == 0
    assert page.stat().st_size > 10_000


def test_torch_threads_are_bounded(capsys):
    assert exit_status(train_cli.cli, ["--threads", "1000"]) == 2
    assert "--threads=1000 is too large" in capsys.readouterr().err


def test_msha_table_continues_an_interrupted_run_instead_of_deleting_it(tmp_path):
    [exp] = [e for e in msha_table.experiments((1,), "de_msfea", 1000, 1000) if e.name.startswith("berlin_p4_-3dB")][:1]
    args = msha_table.Args(run_dir=tmp_path)
    assert "--overwrite" not in msha_table.train_command(exp, args)
    fake_run(tmp_path / exp.name)  # interrupted: last.pt, no best.pt
    command = msha_table.train_command(exp, args)
    assert "--resume" in command and "--overwrite" not in command
    assert "--overwrite" in msha_table.train_command(exp, msha_table.Args(run_dir=tmp_path, retrain=True))


class Reached(Exception):
    """Raised by a stand-in for a command's work: the command got past its checks."""


def _unwritable(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``folder`` without write permission (as root, who writes anyway, os.access says so too)."""
    folder.chmod(0o555)
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == folder else real(p, mode, **kw))


# (what the path is, how to make it in tmp_path, what the one line says)
BAD_OUTPUTS = [
    ("parent is a file", lambda t: (t / "f.txt").write_text("mine") and t / "f.txt" / "x.out", "is a file, not a"),
    ("a folder", lambda t: (t / "folder").mkdir() or t / "folder", "is a folder; give a file name"),
    ("a FIFO", lambda t: os.mkfifo(t / "fifo.out") or t / "fifo.out", "is not a regular file (a FIFO"),
    ("name too long", lambda t: t / ("x" * 300 + ".out"), "File name too long; shorten the path"),
    ("path too long", lambda t: t.joinpath(*["d" * 200] * 25, "x.out"), "File name too long"),
    ("unwritable", lambda t: (t / "ro").mkdir() or t / "ro" / "x.out", "is not writable"),
]


@pytest.mark.parametrize(("what", "make", "message"), BAD_OUTPUTS, ids=[b[0] for b in BAD_OUTPUTS])
def test_an_output_path_that_cannot_be_written_is_one_line_naming_it(tmp_path, monkeypatch, capsys, what, make,
                                                                      message):  # fmt: skip
    path = make(tmp_path)
    if what == "unwritable":
        _unwritable(tmp_path / "ro", monkeypatch)
    monkeypatch.setattr(render, "fly", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    monkeypatch.setattr(benchmark, "fly_all", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    before = snapshot(tmp_path)
    for cli, argv in (
        (render.cli, ["--out", str(path), "--overwrite"]),
        (benchmark.cli, ["--count", "1", "--methods", "straight", "--jobs", "1", "--out-md", str(tmp_path / "b.md"),
                         "--out-csv", str(path), "--overwrite"]),
    ):  # fmt: skip
        assert exit_status(cli, argv) == 2
        err = capsys.readouterr().err
        flag = "--out" if cli is render.cli else "--out-csv"
        assert err.count("\n") == 1 and message in err and f"error: {flag} " in err, err
        assert "[Errno" not in err and "Traceback" not in err and len(err) < 600, err  # a long path shown by its ends
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda t: (t / "file.txt").write_text("mine") and t / "file.txt", "file.txt is a file, not a folder"),
        (lambda t: (t / "file.txt").write_text("mine") and t / "file.txt" / "runs", "Not a directory; a part of the"),
        (lambda t: t.joinpath(*["d" * 200] * 25), "File name too long"),
    ],
    ids=["a file", "below a file", "too long"],
)
def test_train_run_dir_that_cannot_be_made_is_one_line_before_any_env(tmp_path, monkeypatch, capsys, make, message):
    from uamfleet.rl import trainer

    run_dir = make(tmp_path)
    monkeypatch.setattr(trainer, "make_run", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    argv = ["--run-dir", str(run_dir), "--run-name", "r", "--total-timesteps", "64", "--num-envs", "1", "--num-steps",
            "64", "--no-progress", "--no-tensorboard", "--device", "cpu"]  # fmt: skip
    assert exit_status(train_cli.cli, argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error: --run-dir " in err and message in err, err
    assert "[Errno" not in err and len(err) < 800, err


def test_any_os_error_of_a_command_is_one_line_naming_the_path(capsys):
    from uamfleet.cli._common import run

    def main(args: object) -> int:
        raise PermissionError(errno.EACCES, "Permission denied", "/some/where/out.csv")

    @dataclass
    class Args:
        x: int = 0

    assert run(main, Args, [], "uamfleet-x", None) == 2
    err = capsys.readouterr().err
    fix = "choose a folder you may write to (or read from)"
    assert err == f"uamfleet-x: error: Permission denied: '/some/where/out.csv'; {fix}\n"
