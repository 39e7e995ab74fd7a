"""Learning curves of training runs: the greedy evaluations a run logged, TD and PR against agent-steps.

The points come from the run's ``progress.csv`` (:class:`~uamfleet.rl.runs.Logger` writes one row per iteration;
the rows of an evaluation carry ``eval/td_m`` and ``eval/pr_pct``, and ``val_td_m`` / ``val_pr_pct`` where the
run also flew validation instances; the ``eval/*`` values are its TensorBoard scalars too). One run is drawn as
one line; several runs (seeds of one recipe) as thin lines with their median and their range over the agent-steps
at which every run evaluated. :func:`plot_learning_curve` writes the PNG atomically, by default as ``<run>/curve.png``
beside the run's ``tb/`` folder.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, StrMethodFormatter

from uamfleet.checks import ConfigError, check_number
from uamfleet.io import shown_path
from uamfleet.rl.runs import read_progress

if TYPE_CHECKING:
    from matplotlib.axes import Axes

EVALUATION = ("eval/td_m", "eval/pr_pct")
"""progress.csv's columns of the run's own greedy evaluation: mean distance flown (m) and passengers delivered (%)."""
VALIDATION = ("val_td_m", "val_pr_pct")
"""progress.csv's columns of the greedy flights on validation instances (drawn in a second column when logged)."""
NEAR_BEST = 1.05
"""The band drawn above ``best_known``: within 5 % of it."""


@dataclass(frozen=True)
class Curve:
    """The logged evaluations of one run: for each column of :data:`EVALUATION` and :data:`VALIDATION` that the run
    logged, the agent-steps of the rows that carry it and its values there."""

    name: str
    source: Path
    """the progress.csv read"""
    columns: dict[str, tuple[np.ndarray, np.ndarray]]

    def points(self, column: str) -> tuple[np.ndarray, np.ndarray]:
        """(agent-steps, values) of ``column``; empty arrays when the run did not log it."""
        return self.columns.get(column, (np.empty(0), np.empty(0)))


def read_curve(run: Path | str) -> Curve:
    """The evaluations logged by ``run`` (a run folder, or its progress.csv).

    FileNotFoundError when there is no progress.csv; ConfigError when it logs no greedy evaluation."""
    path = Path(run)
    progress = path / "progress.csv" if path.is_dir() else path
    if not progress.is_file():
        raise FileNotFoundError(
            f"{shown_path(progress)} does not exist: give a run folder the trainer wrote (<run_dir>/<run_name>, "
            "holding progress.csv) or the path of its progress.csv."
        )
    rows = read_progress(progress, required=("global_step",))
    columns: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for column in EVALUATION + VALIDATION:
        logged = [(r["global_step"], r[column]) for r in rows if column in r]
        if logged:
            steps, values = zip(*logged, strict=True)
            columns[column] = (np.array(steps, dtype=float), np.array(values, dtype=float))
    if EVALUATION[0] not in columns:
        raise ConfigError(
            f"{shown_path(progress)} logs no greedy evaluation (no {EVALUATION[0]!r} value in its {len(rows)} rows): "
            "train with --eval-every 1 (or any N >= 1) so that the run logs its evaluations, then draw its curve."
        )
    return Curve(progress.parent.name, progress, columns)


def spread(curves: Sequence[Curve], column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(agent-steps, lowest, median, highest) of ``column`` over ``curves``, at the agent-steps at which every curve
    logged it (a run stopped early by its wall-clock cap ends the spread there)."""
    tables = [dict(zip(*c.points(column), strict=True)) for c in curves]
    steps = np.array(sorted(set.intersection(*(set(t) for t in tables))), dtype=float)
    if not len(steps):
        return steps, steps, steps, steps
    values = np.array([[t[s] for s in steps] for t in tables], dtype=float)
    return steps, values.min(axis=0), np.median(values, axis=0), values.max(axis=0)


def draw_learning_curve(
    curves: Sequence[Curve], best_known_m: float | None = None, title: str = "greedy evaluation"
) -> Figure:
    """The figure: greedy TD (top) and PR (bottom) against agent-steps, a second column for the validation
    instances when any run logged them (runs are named by their folder, or by its path when two folders share a
    name); ``best_known_m`` draws that tour's length and the band within 5 % of it in the TD panel of the run's own
    evaluation. Each line's ``gid`` is ``"<column>:<run name>"`` (or ``"<column>:median"``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if not curves:
        raise ConfigError("draw_learning_curve: no run given; pass the curve of one run (or several, one per seed).")

    if len({c.name for c in curves}) < len(curves):  # seeds in folders of one name: tell them apart by their path
        curves = [Curve(str(c.source.parent), c.source, c.columns) for c in curves]
    panels = [(title, EVALUATION)]
    if any(VALIDATION[0] in c.columns for c in curves):
        panels.append(("validation instances (mean)", VALIDATION))
    fig = Figure(figsize=(5.5 * len(panels), 5.5), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, len(panels), sharex=True, squeeze=False, gridspec_kw={"height_ratios": (2, 1)})
    for col, (heading, (td, pr)) in enumerate(panels):
        top, bottom = axes[0, col], axes[1, col]
        if col == 0 and best_known_m is not None:
            top.axhspan(best_known_m, NEAR_BEST * best_known_m, color="tab:green", alpha=0.15, label="within 5 %")
            top.axhline(best_known_m, color="tab:green", ls="--", lw=1, label=f"best_known {best_known_m:,.0f} m")
        _draw(top, curves, td)
        _draw(bottom, curves, pr)
        top.set_title(heading)
        top.set_ylabel("greedy TD [m]")
        bottom.set_ylabel("PR [%]")
        bottom.set_ylim(-5, 105)
        bottom.set_xlabel("agent-steps")
        top.legend(fontsize=7)
        bottom.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x / 1000:g}k" if x else "0"))
        top.yaxis.set_major_formatter(StrMethodFormatter("{x:,.0f}"))
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    names = curves[0].name if len(curves) == 1 else f"{len(curves)} runs"
    fig.suptitle(f"learning curve: {names}")
    return fig


def _draw(ax: Axes, curves: Sequence[Curve], column: str) -> None:
    if len(curves) == 1:
        (curve,) = curves
        ax.plot(
            *curve.points(column), marker="o", ms=3, color="tab:blue", label=curve.name, gid=f"{column}:{curve.name}"
        )
        return
    for c in curves:
        ax.plot(*c.points(column), lw=0.8, alpha=0.4, gid=f"{column}:{c.name}")
    steps, low, median, high = spread(curves, column)
    ax.fill_between(steps, low, high, color="tab:blue", alpha=0.2, label=f"range of {len(curves)} runs")
    ax.plot(steps, median, color="tab:blue", lw=2, label="median", gid=f"{column}:median")


def plot_learning_curve(
    runs: Path | str | Sequence[Path | str],
    out: Path | str | None = None,
    best_known_m: float | None = None,
    title: str = "greedy evaluation",
) -> Path:
    """Draw the learning curve of ``runs`` (one run folder or progress.csv, or several: seeds of one recipe) and
    write it atomically as ``out`` (default: ``curve.png`` in the one run's folder); returns its path."""
    paths = [runs] if isinstance(runs, str | os.PathLike) else list(runs)
    if not paths:
        raise ConfigError("plot_learning_curve: no run given; pass a run folder (or several, one per seed).")
    curves = [read_curve(p) for p in paths]
    if out is None:
        if len(curves) > 1:
            raise ConfigError(f"plot_learning_curve: {len(curves)} runs need an out=<file.png> to draw them in.")
        out = curves[0].source.parent / "curve.png"
    if best_known_m is not None:
        best_known_m = check_number("best_known_m", best_known_m, positive=True)
    from uamfleet.viz.figures import save_figure

    save_figure(draw_learning_curve(curves, best_known_m, title), out)
    return Path(out)


__all__ = ["EVALUATION", "NEAR_BEST", "VALIDATION", "Curve", "draw_learning_curve", "plot_learning_curve", "read_curve",
           "spread"]  # fmt: skip
