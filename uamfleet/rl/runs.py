"""A run's folder, its log and its result: :func:`claim_run` (``run_dir/<name>``, claimed by one command at a
time with a lock file, checked, continued or replaced only when asked), :class:`Logger` (rank 0's
``progress.csv``, TensorBoard events with CleanRL's metric names, progress bar), :func:`read_progress` (the rows
back, for ``--resume`` and the tables) and :class:`TrainResult`.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import re
import shutil
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from uamfleet.checks import ConfigError
from uamfleet.io import PathError, os_error_message, shown_path, write_text_atomic

if TYPE_CHECKING:
    from uamfleet.rl.options import TrainArgs

RUN_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._=+,-]*")
RUN_FILES = ("progress.csv", "last.pt", "best.pt")
LOCK_FILE = "run.lock"
"""The file that claims a run folder while a command writes it (created with ``O_CREAT | O_EXCL``; it holds the
claiming process's pid, host and start time and is removed when the command ends)."""


class RunFolderError(FileExistsError, ConfigError):
    """A run folder that is taken: it holds a run (continue it with --resume, replace it with --overwrite), another
    command is writing it (its lock file), or it is a file. Both a FileExistsError and a ConfigError."""


def check_run_name(name: object, run_dir: Path | str, flag: str = "--run-name") -> str:
    """``name`` if it is one plain folder name (:data:`RUN_NAME`), never a path out of ``run_dir``; the same rule
    for every command that writes a run."""
    if not isinstance(name, str) or not RUN_NAME.fullmatch(name):
        raise ConfigError(
            f"{flag}={name!r} must be one folder name (letters, digits and '._=+,-', not starting with '.'): "
            f"runs live in {run_dir}/<run_name>."
        )
    return name


@dataclass
class RunClaim:
    """A run folder claimed by this process (:func:`claim_run`): its lock file exists until :meth:`release`."""

    folder: Path
    held: tuple[str, ...]
    """the run files the folder held when it was claimed"""
    replace: bool
    """the earlier run is replaced (``overwrite``): :meth:`clear` deletes its files"""
    created: bool
    """the folder held nothing but this claim's lock when claimed (released empty, it is removed again)"""
    _lock_id: tuple[int, int] = (0, 0)

    @property
    def lock(self) -> Path:
        return self.folder / LOCK_FILE

    def clear(self) -> None:
        """Delete the earlier run's files when it is replaced (once the new run's options are checked)."""
        if not self.replace:
            return
        for name in self.held:
            (self.folder / name).unlink(missing_ok=True)
        shutil.rmtree(self.folder / "tb", ignore_errors=True)
        self.replace = False

    def release(self) -> None:
        """Remove the lock file (if still this claim's), and the folder if it held nothing when claimed and is empty."""
        try:
            stat = self.lock.stat()
            if (stat.st_dev, stat.st_ino) == self._lock_id:
                self.lock.unlink()
        except FileNotFoundError:
            pass
        if self.created:
            with contextlib.suppress(OSError):
                self.folder.rmdir()  # only when empty: nothing was written

    def __enter__(self) -> RunClaim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def claim_run(
    run_dir: Path | str, name: object, resume: bool = False, overwrite: bool = False, resumable: bool = True
) -> RunClaim:
    """Claim ``run_dir/name`` for one command, before it does anything else: the folder is made (if new) and its
    lock file created with ``O_CREAT | O_EXCL``, so of two commands claiming one name exactly one wins and the other
    fails at once (:class:`RunFolderError` naming the folder and the lock file). Holding the lock, an existing run
    is refused unless ``resume`` (continue it; FileNotFoundError without its ``last.pt``) or ``overwrite`` (replace
    it: :meth:`RunClaim.clear`). ``resumable``: the command can continue a run (the message offers --resume)."""
    run_dir = Path(run_dir)
    name = check_run_name(name, run_dir)
    if resume and overwrite:
        raise ConfigError("--resume continues the run and --overwrite replaces it: pass one of them.")
    folder = run_dir / name
    created = _open_folder(run_dir, folder)
    lock_id = _take_lock(run_dir, folder, created)
    # Of racing claims the one that made the folder need not be the one that won the lock: the winner owns a folder
    # that held nothing else, whoever made it, and removes it again if the run writes nothing.
    created = created or all(entry.name == LOCK_FILE for entry in folder.iterdir())
    claim = RunClaim(folder, (), replace=False, created=created, _lock_id=lock_id)
    try:
        _check_held(claim, resume, overwrite, resumable)
    except BaseException:
        claim.release()
        raise
    return claim


def _open_folder(run_dir: Path, folder: Path) -> bool:
    """Make ``run_dir`` (if new) and the run folder in it; whether the run folder was new."""
    try:
        if run_dir.exists() and not run_dir.is_dir():
            raise PathError(f"--run-dir {shown_path(run_dir)} is a file, not a folder; give a folder.", path=run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
        return _make_folder(folder)
    except (RunFolderError, PathError):
        raise
    except OSError as err:
        raise _unusable(run_dir, folder, err) from None


def _take_lock(run_dir: Path, folder: Path, created: bool) -> tuple[int, int]:
    """Create the run folder's lock file (exclusively) naming this process; its (device, inode). A folder this
    claim ``created`` is removed again when the lock cannot be made."""
    try:
        fd = os.open(folder / LOCK_FILE, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        raise RunFolderError(_in_use(folder / LOCK_FILE)) from None
    except OSError as err:
        if created:
            folder.rmdir()
        raise _unusable(run_dir, folder, err) from None
    with os.fdopen(fd, "w") as f:
        f.write(f"pid={os.getpid()} host={socket.gethostname()} since={time.strftime('%Y-%m-%dT%H:%M:%S%z')}\n")
        stat = os.fstat(f.fileno())
    return stat.st_dev, stat.st_ino


def _check_held(claim: RunClaim, resume: bool, overwrite: bool, resumable: bool) -> None:
    """Record the run files the claimed folder holds; refuse an existing run unless ``resume`` or ``overwrite``
    (which marks it for :meth:`RunClaim.clear`), and a ``resume`` without ``last.pt``."""
    folder = claim.folder
    claim.held = tuple(f for f in RUN_FILES if (folder / f).exists())
    if claim.held and not resume:
        if not overwrite:
            offer = (
                "continue it with --resume, replace it with --overwrite" if resumable else "replace it with --overwrite"
            )
            raise RunFolderError(
                f"{folder} already holds a run ({', '.join(claim.held)}); {offer}, or choose another --run-name."
            )
        claim.replace = True
    if resume and not (folder / "last.pt").exists():
        raise FileNotFoundError(f"--resume: no checkpoint at {folder / 'last.pt'}; train without --resume first.")


def _unusable(run_dir: Path, folder: Path, err: OSError) -> PathError:
    return PathError(
        f"--run-dir {shown_path(run_dir)}: cannot create the run folder {shown_path(folder)}: "
        f"{os_error_message(err, with_path=False)}.",
        err,
    )


def _make_folder(folder: Path) -> bool:
    """Make the run folder; whether it was new. RunFolderError when the name is taken by a file."""
    try:
        folder.mkdir()
        return True
    except FileExistsError:
        if not folder.is_dir():
            raise RunFolderError(
                f"{folder} is a file, not a run folder; move it away or choose another --run-name."
            ) from None
        return False


def _in_use(lock: Path) -> str:
    """The message for a run folder whose lock file exists: who holds it, and how to clear a stale one."""
    try:
        holder = " ".join(lock.read_text(errors="replace").split())[:200]
    except OSError:
        holder = ""
    fields = dict(part.split("=", 1) for part in holder.split(" ") if "=" in part)
    who = f"pid {fields.get('pid', '?')} on {fields.get('host', '?')} since {fields.get('since', '?')}"
    stale = ""
    if (
        fields.get("host") == socket.gethostname()
        and fields.get("pid", "").isdigit()
        and not _alive(int(fields["pid"]))
    ):
        stale = f" (no process {fields['pid']} runs on this host now: the lock looks stale)"
    return (
        f"{lock.parent} is in use by another run: its lock file {lock} was made by {who}{stale}; wait for that run "
        f"to end or choose another --run-name; if no run uses the folder any more (one was killed), delete {lock}."
    )


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: it exists
        return True
    return True


def run_folder(args: TrainArgs) -> Path:
    """run_dir/<name>, checked (:func:`claim_run`) and, with ``overwrite``, emptied of the earlier run; the lock is
    released again (a command that writes the run holds its :class:`RunClaim` instead)."""
    with claim_run(args.run.run_dir, args.name, resume=args.run.resume, overwrite=args.run.overwrite) as claim:
        claim.clear()
        claim.created = False  # the caller writes into it
    return claim.folder


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
        if args.run.tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            purge = None if resumed_at_step is None else resumed_at_step + 1
            self.writer = SummaryWriter(str(folder / "tb"), purge_step=purge)
            self.writer.add_text("hyperparameters", "|param|value|\n|-|-|\n" + "\n".join(
                f"|{k}|{v}|" for k, v in args.flat().items()))  # fmt: skip
        self.bar = _progress(args.run.progress, num_iterations, done_iterations)

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


def read_progress(path: Path, required: tuple[str, ...] = ()) -> list[dict[str, float]]:
    """The rows of a run's ``progress.csv`` as floats (empty cells left out; no file: no rows). A cell that is not a
    number, or a row without a ``required`` column, is a ConfigError naming the file, the row and the column."""
    if not path.exists():
        return []
    rows = []
    try:
        with path.open(encoding="utf-8", newline="") as f:
            for line, r in enumerate(csv.DictReader(f), start=2):  # line 1 is the header
                rows.append({k: _cell(path, line, k, v) for k, v in r.items() if v not in ("", None)})
                if missing := [k for k in required if k not in rows[-1]]:
                    raise ConfigError(f"{path} line {line}: no {missing[0]!r}; {_PROGRESS_FIX}.")
    except (UnicodeDecodeError, csv.Error) as err:
        raise ConfigError(f"{path} is not a progress.csv uamfleet wrote ({err}); {_PROGRESS_FIX}") from None
    return rows


_PROGRESS_FIX = (
    "restore it from a copy, delete the rows after the checkpoint's iteration that are damaged, or delete the file "
    "(--resume then logs the iterations after the checkpoint only)"
)


def _cell(path: Path, line: int, column: str | None, value: str | list[str]) -> float:
    if column is None or not isinstance(value, str):  # a row with more cells than the header has columns
        raise ConfigError(f"{path} line {line}: more cells than the header's columns; {_PROGRESS_FIX}.")
    try:
        return float(value)
    except ValueError:
        raise ConfigError(
            f"{path} line {line}, column {column!r}: {value[:40]!r} is not a number; {_PROGRESS_FIX}."
        ) from None
