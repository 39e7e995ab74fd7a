"""A run's folder, its log and its result: :func:`run_folder` (``run_dir/<name>``, checked, continued or replaced
only when asked), :class:`Logger` (rank 0's ``progress.csv``, TensorBoard events with CleanRL's metric names,
progress bar), :func:`read_progress` (the rows back, for ``--resume`` and the tables) and :class:`TrainResult`.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from uamfleet.io import write_text_atomic

if TYPE_CHECKING:
    from uamfleet.rl.options import TrainArgs

RUN_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._=+,-]*")
RUN_FILES = ("progress.csv", "last.pt", "best.pt")


def run_folder(args: TrainArgs) -> Path:
    """run_dir/<name>, checked: one folder name, never a path out of run_dir; an existing run is continued
    only with ``resume``, replaced only with ``overwrite``."""
    name = args.name
    if not RUN_NAME.fullmatch(name):
        raise ValueError(
            f"run_name={name!r} must be one folder name (letters, digits and '._=+,-', not starting with '.'): "
            f"runs live in {args.run_dir}/<run_name>."
        )
    if args.resume and args.overwrite:
        raise ValueError("--resume continues the run and --overwrite replaces it: pass one of them.")
    folder = args.run_dir / name
    held = [f for f in RUN_FILES if (folder / f).exists()]
    if held and not args.resume:
        if not args.overwrite:
            raise FileExistsError(
                f"{folder} already holds a run ({', '.join(held)}); continue it with --resume, replace it with "
                "--overwrite, or choose another --run-name."
            )
        for f in held:
            (folder / f).unlink()
        shutil.rmtree(folder / "tb", ignore_errors=True)
    if args.resume and not (folder / "last.pt").exists():
        raise FileNotFoundError(f"--resume: no checkpoint at {folder / 'last.pt'}; train without --resume first.")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@dataclass
class TrainResult:
    """What :func:`uamfleet.rl.trainer.train` returns: where the run is, how far it got, its evaluations."""

    run_dir: Path
    global_step: int
    iterations: int
    wall_s: float
    final_eval: dict[str, float]
    best_eval: dict[str, float]
    best_step: int
    target_reached_step: int | None = None
    target_reached_s: float | None = None
    losses: list[dict[str, float]] = field(default_factory=list)
    interrupted: bool = False
    rank: int = 0
    """torch.distributed rank (under torchrun only rank 0 logs, so only its rows and evaluations are filled)"""


class Logger:
    """Rank 0's progress.csv, TensorBoard events and progress bar. A resumed run's TensorBoard continues after
    the checkpoint's step (``resumed_at_step``): events logged later (iterations trained again) are purged, its own
    are kept."""

    def __init__(
        self, folder: Path, args: TrainArgs, num_iterations: int, done_iterations: int, resumed_at_step: int | None
    ) -> None:
        self.folder, self.writer = folder, None
        if args.tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            purge = None if resumed_at_step is None else resumed_at_step + 1
            self.writer = SummaryWriter(str(folder / "tb"), purge_step=purge)
            self.writer.add_text("hyperparameters", "|param|value|\n|-|-|\n" + "\n".join(
                f"|{k}|{v}|" for k, v in dataclasses.asdict(args).items()))  # fmt: skip
        self.bar = _progress(args.progress, num_iterations, done_iterations)

    def write(self, rows: list[dict[str, float]], best: dict[str, float]) -> None:
        row = rows[-1]
        _log(self.writer, row, int(row["global_step"]))
        write_text_atomic(self.folder / "progress.csv", _csv(rows))
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix_str(_postfix(row, best))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        if self.writer is not None:
            self.writer.close()


def _progress(enabled: bool, total: int, initial: int) -> Any:
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="it", dynamic_ncols=True)


def _postfix(row: dict[str, float], best: dict[str, float]) -> str:
    parts = []
    if "charts/episodic_return" in row:
        parts.append(f"return {row['charts/episodic_return']:.0f}")
        parts.append(f"train PR {100 * row['charts/service_rate']:.0f}%")
    if "eval/pr_pct" in row:
        parts.append(f"eval PR {row['eval/pr_pct']:.0f}% TD {row['eval/td_m']:.0f} m")
    if best:
        parts.append(f"best PR {best['pr_pct']:.0f}% TD {best['td_m']:.0f} m")
    return ", ".join(parts)


def _log(writer: Any, row: dict[str, float], step: int) -> None:
    if writer is None:
        return
    for key, value in row.items():
        if "/" in key and isinstance(value, float | int) and math.isfinite(value):
            writer.add_scalar(key, value, step)


def _csv(rows: list[dict[str, float]]) -> str:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    # counters stay integers when a resumed run writes back the rows it read (as floats)
    writer.writerows({**r, **{k: int(r[k]) for k in ("iteration", "global_step") if k in r}} for r in rows)
    return buffer.getvalue()


def read_progress(path: Path) -> list[dict[str, float]]:
    """The rows of a run's ``progress.csv`` as floats (empty cells left out; no file: no rows)."""
    if not path.exists():
        return []
    with path.open() as f:
        return [{k: float(v) for k, v in r.items() if v not in ("", None)} for r in csv.DictReader(f)]
