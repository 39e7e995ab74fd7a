"""One command at a time writes a run folder: the folder is claimed (a lock file created with O_EXCL) before any env
is built, by every command that writes a run (train, imitate, quickstart through train, torchrun's rank 0); a
second run of the name fails at once naming the folder and the lock; run names are one plain folder name for
every command; a damaged progress.csv on --resume names the file, the line and the column."""

from __future__ import annotations

import contextlib
import io
import os
import threading
import traceback
from pathlib import Path

import pytest

from uamfleet.cli import imitate as imitate_cli
from uamfleet.cli import train as train_cli
from uamfleet.rl import imitation, trainer
from uamfleet.rl.distributed import launch_local
from uamfleet.rl.imitation import ImitationArgs
from uamfleet.rl.runs import LOCK_FILE, RunFolderError, claim_run
from uamfleet.rl.trainer import TrainArgs, train


class Reached(Exception):
    """Raised by a stand-in for the expensive part of a command: the command got past its claim."""


def exit_status(cli, argv: list[str]) -> int:
    try:
        return cli(argv)
    except SystemExit as done:
        return int(done.code or 0)


def tiny(run_dir: Path, **overrides) -> TrainArgs:
    fields = dict(run_dir=run_dir, run_name="r", total_timesteps=64, num_envs=1, num_steps=64, progress=False,
                  tensorboard=False, device="cpu")  # fmt: skip
    return TrainArgs.from_flat({**fields, **overrides})


def test_of_many_concurrent_claims_of_one_name_exactly_one_wins(tmp_path):
    racers = 8
    start = threading.Barrier(racers)
    won, lost, other = [], [], []

    def claim() -> None:
        start.wait()
        try:
            won.append(claim_run(tmp_path, "r"))
        except RunFolderError as err:
            lost.append(str(err))
        except BaseException as err:  # anything else is a bug of the claim
            other.append(repr(err))

    threads = [threading.Thread(target=claim) for _ in range(racers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert other == [] and len(won) == 1 and len(lost) == racers - 1
    lock = tmp_path / "r" / LOCK_FILE
    assert all(f"{tmp_path / 'r'} is in use by another run" in m and f"delete {lock}" in m for m in lost)
    assert f"pid={os.getpid()} " in lock.read_text()
    won[0].release()
    assert not (tmp_path / "r").exists()  # the claim made the folder and nothing was written into it
    claim_run(tmp_path, "r").release()  # free again


def test_a_second_training_of_a_name_fails_at_once_while_the_first_runs(tmp_path, monkeypatch, capsys):
    entered, finish = threading.Event(), threading.Event()
    builds: list[str] = []

    def make_run(*args, **kwargs):  # the env set-up: the first training waits here, holding its claim
        builds.append(threading.current_thread().name)
        if threading.current_thread().name == "first":
            entered.set()
            finish.wait(30)
        raise Reached

    monkeypatch.setattr(trainer, "make_run", make_run)
    outcome: list[BaseException] = []

    def first() -> None:
        try:
            train(tiny(tmp_path))
        except BaseException as err:
            outcome.append(err)

    thread = threading.Thread(target=first, name="first")
    thread.start()
    try:
        assert entered.wait(30)
        with pytest.raises(RunFolderError, match=f"{tmp_path / 'r'} is in use by another run.*{LOCK_FILE}"):
            train(tiny(tmp_path, overwrite=True))  # --overwrite replaces a finished run, never a running one
        argv = ["--run-dir", str(tmp_path), "--run-name", "r", "--total-timesteps", "64", "--num-envs", "1",
                "--num-steps", "64", "--no-progress", "--no-tensorboard", "--device", "cpu"]  # fmt: skip
        assert exit_status(train_cli.cli, argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is in use by another run" in err and str(tmp_path / "r" / LOCK_FILE) in err
        assert builds == ["first"]  # the second and third never built an env
    finally:
        finish.set()
        thread.join(30)
    assert len(outcome) == 1 and isinstance(outcome[0], Reached)
    assert not (tmp_path / "r").exists()  # released: the lock gone, the empty folder it made removed
    with pytest.raises(Reached):
        train(tiny(tmp_path))  # the name is free again


def test_a_stale_lock_says_whose_it_is_and_how_to_clear_it(tmp_path):
    folder = tmp_path / "r"
    folder.mkdir()
    import socket

    dead = 2**22 + 12345  # above Linux's default pid_max: no such process
    (folder / LOCK_FILE).write_text(f"pid={dead} host={socket.gethostname()} since=2026-01-01T00:00:00+0000\n")
    with pytest.raises(RunFolderError) as caught:
        claim_run(tmp_path, "r")
    message = str(caught.value)
    assert f"pid {dead} on {socket.gethostname()}" in message and "looks stale" in message
    assert f"delete {folder / LOCK_FILE}" in message
    (folder / LOCK_FILE).unlink()
    claim_run(tmp_path, "r").release()


def test_an_existing_run_is_refused_under_the_lock_and_the_lock_released(tmp_path):
    folder = tmp_path / "r"
    folder.mkdir()
    (folder / "last.pt").write_bytes(b"a run someone cares about")
    with pytest.raises(RunFolderError, match=r"already holds a run \(last.pt\); continue it with --resume"):
        claim_run(tmp_path, "r")
    assert sorted(p.name for p in folder.iterdir()) == ["last.pt"]
    with claim_run(tmp_path, "r", overwrite=True) as claim:
        assert (folder / "last.pt").exists()  # deleted only once the run's options are checked
        claim.clear()
        assert sorted(p.name for p in folder.iterdir()) == [LOCK_FILE]
    assert list(folder.iterdir()) == []


def test_a_command_that_cannot_resume_offers_only_overwrite(tmp_path):
    folder = tmp_path / "r"
    folder.mkdir()
    (folder / "best.pt").write_bytes(b"a run")
    with pytest.raises(RunFolderError) as caught:
        claim_run(tmp_path, "r", resumable=False)
    assert str(caught.value) == (
        f"{folder} already holds a run (best.pt); replace it with --overwrite, or choose another --run-name."
    )
    assert sorted(p.name for p in folder.iterdir()) == ["best.pt"]  # the lock released


def test_a_lock_that_cannot_be_made_names_the_folder_and_removes_the_folder_it_made(tmp_path, monkeypatch):
    real = os.open

    def refuse_lock(path, *args, **kwargs):
        if Path(path).name == LOCK_FILE:
            raise PermissionError(13, "Permission denied", str(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", refuse_lock)
    with pytest.raises(OSError) as caught:
        claim_run(tmp_path, "r")
    assert str(caught.value).startswith(
        f"--run-dir {tmp_path}: cannot create the run folder {tmp_path / 'r'}: Permission denied"
    )
    assert not (tmp_path / "r").exists()  # made by this claim, removed again
    (tmp_path / "kept").mkdir()
    with pytest.raises(OSError, match="cannot create the run folder"):
        claim_run(tmp_path, "kept")
    assert (tmp_path / "kept").is_dir()  # someone else's folder stays


@pytest.mark.parametrize("name", ["/abs/path", "../x", "a/b", ".hidden"])
def test_imitate_refuses_a_path_as_run_name_as_train_does(tmp_path, monkeypatch, capsys, name):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(imitation, "_groups", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    monkeypatch.setattr(imitation, "validation_metrics", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    for cli, flag in ((imitate_cli.cli, []), (train_cli.cli, ["--total-timesteps", "64"])):
        assert exit_status(cli, ["--run-name", name, *flag]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"--run-name={name!r} must be one folder name" in err, err
    assert list(tmp_path.rglob("*")) == []  # nothing written, here or (for ../x) beside it
    assert not Path("/abs/path").exists() and not (tmp_path.parent / "x").exists()


def test_imitate_claims_its_folder_before_any_work(tmp_path, monkeypatch):
    monkeypatch.setattr(imitation, "_groups", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    args = ImitationArgs.from_flat(dict(run_dir=tmp_path, run_name="dagger", overwrite=True, eval_instances=1))
    with claim_run(tmp_path, "dagger"):  # another command writes the run
        with pytest.raises(RunFolderError, match=f"{tmp_path / 'dagger'} is in use by another run"):
            imitation.imitate(args)
    with pytest.raises(Reached):
        imitation.imitate(args)  # free: it gets to its work
    assert not (tmp_path / "dagger").exists()  # and leaves no empty folder or lock behind when it fails


def test_resume_with_a_damaged_progress_csv_names_the_file_line_and_column(tmp_path, monkeypatch, capsys):
    folder = tmp_path / "r"
    folder.mkdir()
    (folder / "last.pt").write_bytes(b"not read before the log is checked")
    (folder / "progress.csv").write_text("iteration,global_step\n1,64\n2,abc\n")
    monkeypatch.setattr(trainer, "make_run", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    argv = ["--run-dir", str(tmp_path), "--run-name", "r", "--resume", "--total-timesteps", "64", "--num-envs", "1",
            "--num-steps", "64", "--no-progress", "--no-tensorboard", "--device", "cpu"]  # fmt: skip
    assert exit_status(train_cli.cli, argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"{folder / 'progress.csv'} line 3, column 'global_step': 'abc' is not a number" in err
    assert "delete the file" in err  # what to do
    assert sorted(p.name for p in folder.iterdir()) == ["last.pt", "progress.csv"]  # the lock released


def _rank_runs_train_cli(run_dir: str, out: str) -> None:
    """One torchrun rank running the train command on an existing run; its exit status and stderr to files."""
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr):
        try:
            argv = ["--run-dir", run_dir, "--run-name", "r", "--total-timesteps", "128", "--num-envs", "2",
                    "--num-steps", "64", "--no-progress", "--no-tensorboard", "--device", "cpu"]  # fmt: skip
            code = train_cli.cli(argv)
        except BaseException:
            traceback.print_exc()
            code = -1
    rank = os.environ["RANK"]
    Path(f"{out}_rank{rank}.txt").write_text(f"{code}\n{stderr.getvalue()}")


def test_torchrun_on_an_existing_run_name_is_one_line_from_rank_0(tmp_path):
    folder = tmp_path / "runs" / "r"
    folder.mkdir(parents=True)
    (folder / "progress.csv").write_text("iteration,global_step\n1,64\n")
    (folder / "last.pt").write_bytes(b"a run someone cares about")
    launch_local(2, _rank_runs_train_cli, str(tmp_path / "runs"), str(tmp_path / "out"))
    code0, err0 = (tmp_path / "out_rank0.txt").read_text().split("\n", 1)
    code1, err1 = (tmp_path / "out_rank1.txt").read_text().split("\n", 1)
    assert code0 == "2" and err0.count("\n") == 1 and f"{folder} already holds a run (progress.csv, last.pt)" in err0
    assert code1 == "2" and err1 == ""  # rank 1 says nothing: no second line, no traceback
    assert sorted(p.name for p in folder.iterdir()) == ["last.pt", "progress.csv"]


def test_quickstart_claims_through_train_before_any_env(tmp_path, monkeypatch, capsys):
    from uamfleet.cli import quickstart

    monkeypatch.setattr(trainer, "make_run", lambda *a, **k: (_ for _ in ()).throw(Reached()))
    argv = ["--run-dir", str(tmp_path), "--run-name", "mine", "--no-generalist", "--threads", "1"]
    with claim_run(tmp_path, "mine"):  # a training of that name is running
        assert exit_status(quickstart.cli, argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{tmp_path / 'mine'} is in use by another run" in err, err


def test_a_run_folder_that_cannot_be_made_names_it_and_the_flag(tmp_path, monkeypatch):
    real = Path.mkdir

    def mkdir(self, *args, **kwargs):
        if self.name == "r":
            raise PermissionError(13, "Permission denied", str(self))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", mkdir)
    with pytest.raises(OSError) as caught:
        claim_run(tmp_path, "r")
    assert str(caught.value) == (
        f"--run-dir {tmp_path}: cannot create the run folder {tmp_path / 'r'}: Permission denied; choose a folder you "
        "may write to (or read from)."
    )
