"""The learning curve (uamfleet/viz/curves.py) and the quickstart's curve.png: the points drawn are the evaluations
the run logged in its progress.csv (read back here with the csv module, not with the code under test), several
seeds are drawn with their median and range, and a run that logged no evaluation is refused in one line."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import small_config
from PIL import Image

from uamfleet.checks import ConfigError
from uamfleet.cli import quickstart
from uamfleet.config import Request
from uamfleet.metrics import EpisodeMetrics
from uamfleet.rl.runs import TrainResult
from uamfleet.rl.trainer import TrainArgs, train
from uamfleet.viz.curves import draw_learning_curve, plot_learning_curve, read_curve, spread
from uamfleet.viz.figures import save_figure

ROOT = Path(__file__).resolve().parents[2]
HEADER = "iteration,global_step,wall_s,charts/learning_rate,losses/value_loss,eval/td_m,eval/pr_pct"


def logged(folder: Path, text: str) -> Path:
    """A run folder holding ``text`` as its progress.csv (the trainer's columns; an empty cell: no evaluation)."""
    folder.mkdir(parents=True)
    (folder / "progress.csv").write_text(text)
    return folder


def lines(fig: Any) -> dict[str, np.ndarray]:
    """gid -> the [N, 2] (agent-steps, value) points of every line of ``fig`` that has a gid."""
    return {line.get_gid(): line.get_xydata() for ax in fig.axes for line in ax.lines if line.get_gid()}


def csv_points(progress: Path, column: str) -> np.ndarray:
    """(global_step, column) of the rows of ``progress`` that carry ``column``, read with the csv module."""
    with progress.open() as f:
        return np.array([(float(r["global_step"]), float(r[column])) for r in csv.DictReader(f) if r.get(column)])


def png_bytes(fig: Any, folder: Path) -> bytes:
    save_figure(fig, folder / "expected.png")
    return (folder / "expected.png").read_bytes()


def test_the_curve_of_a_trained_run_is_its_logged_evaluations(tmp_path):
    """A tiny run of the trainer (3 iterations, evaluated every 2nd and at the last): the plotted points are the
    rows of its progress.csv that carry an evaluation, and curve.png is that figure, written beside the run."""
    args = TrainArgs.from_flat(dict(
        total_timesteps=3 * 16 * 2, num_envs=2, num_steps=16, num_minibatches=1, update_epochs=1, eval_every=2,
        run_dir=tmp_path, run_name="tiny", progress=False, tensorboard=False, threads=1, time_limit_steps=30,
        eval_time_limit_steps=30, d_model=16, num_heads=2, seed=3,
    ))  # fmt: skip
    config = small_config(requests=(Request(0, (350.0, 150.0), (350.0, 350.0)),), time_limit_steps=30)
    folder = train(args, env_config=config).run_dir
    td, pr = csv_points(folder / "progress.csv", "eval/td_m"), csv_points(folder / "progress.csv", "eval/pr_pct")
    assert td[:, 0].tolist() == [64.0, 96.0]  # iterations 2 and 3 (the last) of 32 agent-steps each
    fig = draw_learning_curve([read_curve(folder)])
    drawn = lines(fig)
    np.testing.assert_array_equal(drawn["eval/td_m:tiny"], td)
    np.testing.assert_array_equal(drawn["eval/pr_pct:tiny"], pr)
    assert plot_learning_curve(folder) == folder / "curve.png"
    written = (folder / "curve.png").read_bytes()
    assert written == png_bytes(fig, tmp_path)
    image = Image.open(io.BytesIO(written))
    image.load()
    assert image.format == "PNG" and image.size == (605, 605)  # 5.5 in x 110 dpi


def test_several_seeds_are_drawn_with_their_median_and_range(tmp_path):
    """Three seeds evaluated at 0, 64 and 128 agent-steps (the third stopped early: the spread ends at 64); the
    median and range are computed here by hand."""
    a = logged(tmp_path / "s1" / "quickstart", f"{HEADER}\n0,0,0.1,3e-4,,5200,100\n1,64,1.0,3e-4,2.0,5000,100\n"
                                                "2,128,2.0,3e-4,1.0,4900,100\n")  # fmt: skip
    b = logged(tmp_path / "s2" / "quickstart", f"{HEADER}\n0,0,0.1,3e-4,,7000,50\n1,64,1.0,3e-4,2.0,5400,100\n"
                                                "2,128,2.0,3e-4,1.0,5100,100\n")  # fmt: skip
    c = logged(tmp_path / "s3" / "quickstart", f"{HEADER}\n0,0,0.1,3e-4,,6000,75\n1,64,1.0,3e-4,2.0,5100,100\n")
    curves = [read_curve(p) for p in (a, b, c)]
    steps, low, median, high = spread(curves, "eval/td_m")
    assert steps.tolist() == [0.0, 64.0]
    assert (low.tolist(), median.tolist(), high.tolist()) == ([5200.0, 5000.0], [6000.0, 5100.0], [7000.0, 5400.0])
    fig = draw_learning_curve(curves, best_known_m=4900.0)
    drawn = lines(fig)
    np.testing.assert_array_equal(drawn["eval/td_m:median"], [[0, 6000], [64, 5100]])
    np.testing.assert_array_equal(drawn["eval/pr_pct:median"], [[0, 75], [64, 100]])
    for folder in (a, b, c):  # each seed's own line, named by its path (all three folders are "quickstart")
        np.testing.assert_array_equal(drawn[f"eval/td_m:{folder}"], csv_points(folder / "progress.csv", "eval/td_m"))
    top = fig.axes[0]
    band = [p for p in top.patches if p.get_label() == "within 5 %"]
    assert len(band) == 1 and band[0].get_y() == 4900.0 and band[0].get_height() == pytest.approx(245.0)
    out = plot_learning_curve([a, b, c], tmp_path / "seeds.png", best_known_m=4900.0)
    assert out.read_bytes() == png_bytes(fig, tmp_path)
    with pytest.raises(ConfigError, match=r"3 runs need an out=<file.png>"):
        plot_learning_curve([a, b, c])


def test_validation_instances_get_a_column_of_their_own(tmp_path):
    run = logged(tmp_path / "v", f"{HEADER},val_td_m,val_pr_pct\n1,64,1.0,3e-4,2.0,5000,100,9000,95\n"
                                  "2,128,2.0,3e-4,1.0,4900,100,8800,100\n")  # fmt: skip
    fig = draw_learning_curve([read_curve(run)])
    assert len(fig.axes) == 4 and fig.axes[1].get_title() == "validation instances (mean)"
    drawn = lines(fig)
    np.testing.assert_array_equal(drawn["val_td_m:v"], [[64, 9000], [128, 8800]])
    np.testing.assert_array_equal(drawn["val_pr_pct:v"], [[64, 95], [128, 100]])


def test_a_log_without_evaluations_is_refused_in_one_line(tmp_path):
    run = logged(tmp_path / "r", "iteration,global_step,wall_s,eval/td_m\n1,64,1.0,\n2,128,2.0,\n")
    with pytest.raises(ConfigError) as caught:
        plot_learning_curve(run)
    message = str(caught.value)
    assert "\n" not in message and "logs no greedy evaluation" in message and "--eval-every 1" in message
    assert str(run / "progress.csv") in message and not (run / "curve.png").exists()
    with pytest.raises(FileNotFoundError, match=r"/nowhere does not exist: give a run folder the trainer wrote"):
        plot_learning_curve(tmp_path / "nowhere")
    with pytest.raises(ConfigError, match=r"no run given"):
        plot_learning_curve([])
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match=r"/empty/progress.csv does not exist: give a run folder"):
        plot_learning_curve(tmp_path / "empty")


def test_the_quickstart_draws_its_curve_beside_the_run_and_names_it(tmp_path, monkeypatch, capsys):
    """The quickstart after training (the trainer and the flights stubbed: they are not what is tested): it writes
    curve.png in the run folder, with best_known's recorded tour on P4 at -3 dB, and prints its path."""
    folder = tmp_path / "quickstart"

    def trained(args: TrainArgs) -> TrainResult:
        logged(folder, f"{HEADER}\n0,0,0.1,,,5000,100\n1,2048,3.0,3e-4,2.0,5000,100\n")
        return TrainResult(folder, 2048, 1, 3.0, {}, {}, 0)

    metrics = EpisodeMetrics(
        5000.0, 100.0, 59.0, 28.0, 100.0, 91.6, -2.0, 200.0, 4, 4, 50.0, 60.0, 1.2, 1.0, 0, 0.1, 50
    )
    monkeypatch.setattr(quickstart, "train", trained)
    monkeypatch.setattr(quickstart, "load_policy", lambda path: (None, TrainArgs()))  # a run's options: de_msfea
    monkeypatch.setattr(quickstart, "fly", lambda *a, **k: metrics)
    monkeypatch.chdir(ROOT)  # the recorded rows are read from docs/results/, as when the README's command runs
    assert quickstart.cli(["--run-dir", str(tmp_path), "--no-generalist"]) == 0
    out = capsys.readouterr().out
    where = "on P4 and on 10 validation instances"  # the default --curve-instances
    assert f"\nlearning curve (greedy TD and PR against agent-steps, {where}): {folder / 'curve.png'}\n" in out
    fig = draw_learning_curve([read_curve(folder)], best_known_m=4900.0, title="Berlin P4 at -3 dB")
    assert (folder / "curve.png").read_bytes() == png_bytes(fig, tmp_path)


def test_the_quickstart_reads_best_known_at_its_threshold_and_rule():
    fixed = ROOT / "docs" / "results" / "benchmark_fixed.csv"
    assert quickstart.recorded_best_known(quickstart.Args(), fixed) == 4900.0
    assert quickstart.recorded_best_known(quickstart.Args(feasibility="segment_raster"), fixed) == 5100.0
    assert quickstart.recorded_best_known(quickstart.Args(sinr_min_db=-7.0), fixed) == 4700.0
    assert quickstart.recorded_best_known(quickstart.Args(sinr_min_db=-3.5), fixed) is None
    assert quickstart.recorded_best_known(quickstart.Args(), fixed.with_name("absent.csv")) is None
