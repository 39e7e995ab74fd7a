"""The one command, ``uamfleet <command> [options]``: it lists its commands, reaches every console script's module
with that script's options, help and errors under the prog ``uamfleet <command>``, answers an unknown command or
option in one line with exit status 2, and imports only the module of the command that runs."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from collections.abc import Callable
from importlib import import_module
from pathlib import Path

import pytest

from uamfleet.cli import main as uamfleet_cmd
from uamfleet.cli.main import ALIASES, COMMANDS, cli, summary

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
SCRIPTS: dict[str, str] = PYPROJECT["project"]["scripts"]


def outcome(run: Callable[[], int], capsys) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of ``run``; tyro's ``--help`` and usage errors end in SystemExit."""
    try:
        status = run()
    except SystemExit as done:
        status = int(done.code or 0)
    out, err = capsys.readouterr()
    return status, out, err


def test_pyproject_installs_the_command() -> None:
    assert SCRIPTS["uamfleet"] == "uamfleet.cli.main:cli"


@pytest.mark.parametrize("script", sorted(set(SCRIPTS) - {"uamfleet"}))
def test_every_console_script_is_a_command_of_the_same_module(script: str) -> None:
    # A new uamfleet-<name> script without its `uamfleet <name>` command fails here.
    name = script.removeprefix("uamfleet-")
    assert name in COMMANDS or name in ALIASES, f"{script} has no `uamfleet {name}`: add it to COMMANDS or ALIASES"
    command = ALIASES.get(name, name)
    assert f"uamfleet.cli.{COMMANDS[command]}:cli" == SCRIPTS[script]


def test_help_lists_every_command_once_with_its_modules_summary(capsys) -> None:
    status, out, err = outcome(lambda: cli(["--help"]), capsys)
    assert status == 0 and err == ""
    assert out.startswith("usage: uamfleet <command> [options]\n")
    listed = [line.split(maxsplit=1) for line in out.splitlines() if re.match(r"  [a-z]", line)]
    assert [name for name, _ in listed] == list(COMMANDS)
    for name, text in listed:
        module = import_module(f"uamfleet.cli.{COMMANDS[name]}")
        assert text == summary(module.__doc__), name  # read from the file, equal to the imported docstring's
        assert text.split()[0] == (module.__doc__ or "").split()[0], (name, text)
        assert 20 < len(text) <= 80 and "\n" not in text, (name, text)


def test_the_command_alone_lists_the_commands_on_stderr_and_exits_2(capsys) -> None:
    status, out, err = outcome(lambda: cli([]), capsys)
    assert status == 2 and out == ""
    assert err.startswith("usage: uamfleet <command> [options]\n") and all(f"\n  {c} " in err for c in COMMANDS)


def test_version_is_pyprojects(capsys) -> None:
    expected = (0, f"uamfleet {PYPROJECT['project']['version']}\n", "")
    for flag in ("--version", "-V"):
        assert outcome(lambda flag=flag: cli([flag]), capsys) == expected


@pytest.mark.parametrize("command", [*COMMANDS, *ALIASES])
def test_a_commands_help_is_its_scripts_help_under_the_new_prog(command: str, capsys) -> None:
    module = import_module(uamfleet_cmd.module_of(command))
    status, new, err = outcome(lambda: cli([command, "--help"]), capsys)
    assert status == 0 and err == ""
    old_status, old, _ = outcome(lambda: module.cli(["--help"]), capsys)
    script = module.cli.__defaults__[-1]
    assert old_status == 0 and old.startswith(f"usage: {script} ")
    old_usage, _, old_rest = old.partition("\n")
    new_usage, _, new_rest = new.partition("\n")
    assert new_usage == old_usage.replace(f"usage: {script} ", f"usage: uamfleet {command} ", 1)
    assert new_rest == old_rest and "--help" in new_rest


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["rollout", "--episodes", "0"], "uamfleet rollout: error: --episodes 0: fly at least one episode"),
     (["train", "--gamma", "2"], "uamfleet train: error: --gamma=2.0 is out of range: it must lie in (0, 1]"),
     (["rollout", "--num-taxi", "2"], "uamfleet rollout: error: Unrecognized options: --num-taxi"),
     (["bench", "--hedge"], "uamfleet bench: error: --hedge searches with a learned policy: give its --checkpoint"),
     (["benchmark", "--hedge"], "uamfleet benchmark: error: --hedge searches with a learned policy")],
)  # fmt: skip
def test_a_bad_option_of_a_command_is_its_one_line_under_the_new_prog(argv: list[str], message: str, capsys) -> None:
    status, out, err = outcome(lambda: cli(argv), capsys)
    assert status == 2 and out == ""
    assert err.startswith(message) and err.count("\n") == 1 and "Traceback" not in err, err


@pytest.mark.parametrize(
    ("word", "suggestion"),
    [("trian", "train"), ("benchmarks", "bench"), ("fleet-benchmarks", "fleet-bench"), ("radiomap", "radio-map"),
     ("xyzzy", None)],
)  # fmt: skip
def test_an_unknown_command_is_one_line_exit_2_with_the_closest_name(word: str, suggestion: str | None, capsys) -> None:
    status, out, err = outcome(lambda: cli([word, "--help"]), capsys)
    assert status == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith(f"uamfleet: error: unknown command '{word}'; the commands are: {', '.join(COMMANDS)}.")
    if suggestion is None:
        assert "Did you mean" not in err
    else:
        assert err.rstrip().endswith(f"Did you mean '{suggestion}'?")


def test_an_option_before_the_command_is_one_line_exit_2(capsys) -> None:
    status, out, err = outcome(lambda: cli(["--scenario", "berlin_p4", "train"]), capsys)
    assert status == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("uamfleet: error: unknown option '--scenario'; give a command first")


@pytest.mark.parametrize(
    ("doc", "expected"),
    [("Fly it (fast) and land.\n\nMore.", "Fly it and land"),
     ("A first sentence. A second one.", "A first sentence"),
     ("Wrapped over\n    two lines (with (nested) asides).", "Wrapped over two lines"),
     ("Score every planner over seeded instances: " + "x " * 40, "Score every planner over seeded instances"),
     ("Tables: " + "word " * 30, "Tables: " + " ".join(["word"] * 14) + "…"),
     ("The main job: one two three, four five six seven eight nine ten eleven twelve, thirteen fourteen",
      "The main job: one two three, four five six seven eight nine ten eleven twelve"),
     (None, "")],
)  # fmt: skip
def test_the_summary_of_a_docstring(doc: str | None, expected: str) -> None:
    assert summary(doc, width=80) == expected


def test_python_m_uamfleet_prints_the_version_and_help_imports_no_command() -> None:
    version = subprocess.run(
        [sys.executable, "-m", "uamfleet", "--version"], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert (version.returncode, version.stdout) == (0, f"uamfleet {PYPROJECT['project']['version']}\n")
    listing = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "uamfleet", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert listing.returncode == 0 and listing.stdout.startswith("usage: python -m uamfleet <command> [options]")
    imported = {line.rsplit("|", 1)[1].strip() for line in listing.stderr.splitlines() if line.count("|") == 2}
    assert "uamfleet.cli.main" in imported
    assert not imported & ({f"uamfleet.cli.{module}" for module in COMMANDS.values()} | {"torch", "tyro"})
