"""The command lines: bad values end in one line on stderr and exit status 2 (never a traceback), the known sets
are choices, every command describes itself, undefined figures print "–", and the console scripts of
pyproject.toml resolve and run from any folder."""

from __future__ import annotations

import math
import re
import subprocess
import sys
import tomllib
from collections.abc import Callable, Sequence
from importlib import import_module
from pathlib import Path

import numpy as np
import pytest

import uamfleet
from uamfleet.cli import benchmark, msha_table, paper_table, quickstart, render, rollout
from uamfleet.cli import train as train_cli
from uamfleet.cli._common import UsageError, fmt, output_path
from uamfleet.rl.trainer import TrainArgs, load_policy, train
from tests.conftest import TINY_FLEET, tiny_train_args

ROOT = Path(__file__).resolve().parents[1]
Cli = Callable[[Sequence[str] | None], int]


def exit_status(cli: Cli, argv: list[str]) -> int:
    try:
        return cli(argv)
    except SystemExit as done:  # tyro's own usage errors (unknown choice, unparsable number) and --help
        return int(done.code or 0)


# (command, arguments, what the one-line message must say)
BAD_VALUES = [
    (rollout.cli, ["--episodes", "0"], "--episodes 0: fly at least one episode"),
    (rollout.cli, ["--episodes", "-2"], "--episodes -2"),
    (rollout.cli, ["--seed", "-5"], "--seed -5: seeds are integers >= 0"),
    (train_cli.cli, ["--total-timesteps", "0"], "--total-timesteps=0 must be an integer >= 1"),
    (train_cli.cli, ["--gamma", "2"], "--gamma=2.0 is out of range: it must lie in (0, 1]"),
    (train_cli.cli, ["--checkpoint-every", "0"], "--checkpoint-every=0 must be an integer >= 1"),
    (train_cli.cli, ["--learning-rate", "-1"], "--learning-rate=-1.0 is out of range: it must lie in (0, inf)"),
    (train_cli.cli, ["--threads", "-1"], "--threads=-1 must be an integer >= 0"),
    (train_cli.cli, ["--gae-lambda", "1.5"], "--gae-lambda=1.5 is out of range: it must lie in [0, 1]"),
    (train_cli.cli, ["--sinr-min-db", "nan"], "--sinr-min-db=nan must be a finite number"),
    (render.cli, ["--out", "/nonexistent/sub/x.html"], "neither its folder /nonexistent/sub nor that folder's parent"),
    (benchmark.cli, ["--methods", "ppo", "--count", "1"], "unknown --methods ['ppo']"),
    (render.cli, ["--checkpoint", "/nonexistent.pt"], "checkpoint /nonexistent.pt does not exist; train one with"),
    (benchmark.cli, ["--from-csv", "/nonexistent.csv"], "No such file or directory: '/nonexistent.csv'"),
    (benchmark.cli, ["--checkpoint", "x.pt", "--guided", "--guided-horizon", "-1"], "--guided-horizon >= 0 (0: to"),
    (benchmark.cli, ["--hedge"], "--hedge searches with a learned policy: give its --checkpoint as well."),
    (benchmark.cli, ["--checkpoint", "x.pt", "--hedge", "--hedge-futures", "0"], "1 <= futures <= 256, commit >= 1"),
]


@pytest.mark.parametrize(("cli", "argv", "message"), BAD_VALUES, ids=[" ".join(c[1]) for c in BAD_VALUES])
def test_a_bad_value_is_one_line_and_exit_2(cli: Cli, argv: list[str], message: str, capsys) -> None:
    assert exit_status(cli, argv) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.endswith("\n"), err  # one line
    assert err.startswith(f"uamfleet-{cli.__module__.rsplit('.', 1)[1].replace('_', '-')}: error: ")
    assert message in err
    assert "Traceback" not in err and out == ""


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--episodes", "abc"], "Error parsing --episodes: invalid literal for int()"),
     (["--num-taxi", "2"], "Unrecognized options: --num-taxi")],
)  # fmt: skip
def test_an_unparsable_value_is_one_line_too(argv: list[str], message: str, capsys) -> None:
    assert exit_status(rollout.cli, argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("uamfleet-rollout: error: ") and message in err and err.count("\n") == 1, err
    assert err.rstrip().endswith("(see uamfleet-rollout --help)")


def test_one_iteration_at_least(tmp_path: Path, capsys) -> None:
    # 100 agent-steps used to train one whole iteration of 2,048 without a word
    argv = ["--total-timesteps", "100", "--run-dir", str(tmp_path)]
    assert exit_status(train_cli.cli, argv) == 2
    err = capsys.readouterr().err
    assert "one iteration's batch of 2048 agent-steps" in err and "raise --total-timesteps to >= 2048" in err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("cli", "flag", "choices"),
    [
        (rollout.cli, "--scenario", uamfleet.SCENARIOS),
        (rollout.cli, "--policy", ("cptsp", "raster_opt", "best_known", "greedy", "random")),
        (render.cli, "--policy", ("raster_replan", "greedy")),
        (train_cli.cli, "--variant", ("le", "de", "de_msfea", "full")),
        (train_cli.cli, "--feasibility", ("endpoint_block", "segment_raster")),
        (train_cli.cli, "--scenario", uamfleet.SCENARIOS),
        (benchmark.cli, "--family", ("berlin",)),
        (quickstart.cli, "--variant", ("de_msfea",)),
        (msha_table.cli, "--main-variant", ("full",)),
    ],
)
def test_a_typo_in_a_known_set_is_a_usage_error_listing_the_choices(cli: Cli, flag: str, choices, capsys) -> None:
    assert exit_status(cli, [flag, "berln"]) == 2
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and err.count("\n") == 1, err  # one line, not tyro's box
    # --policy takes the registry's grammar, checked by uamfleet.policies.parse instead of tyro's choices
    refusal = (
        f"unknown {flag} 'berln'; choose one of"
        if flag == "--policy"
        else f"invalid choice 'berln' for argument '{flag}'"
    )
    assert f"error: {refusal}" in err and all(repr(c) in err for c in choices)
    assert exit_status(cli, ["--help"]) == 0
    help_text = capsys.readouterr().out
    assert all(c in help_text for c in choices)


@pytest.mark.parametrize(
    "module", [rollout, render, train_cli, benchmark, paper_table, msha_table, quickstart], ids=lambda m: m.__name__
)
def test_help_describes_the_command_and_prints_each_default_once(module, capsys, monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    assert exit_status(module.cli, ["--help"]) == 0
    out = capsys.readouterr().out
    first_line = module.__doc__.strip().splitlines()[0]
    assert " ".join(first_line.split()[:6]) in " ".join(out.split()), out[:400]
    assert "(default: the scenario's) (default" not in out
    for line in out.splitlines():  # a wide screen sets sections side by side (a border or a gap between): per cell
        for cell in re.split(r"│| {3,}", line):
            assert cell.count("(default:") <= 1, line


def test_undefined_figures_print_as_a_dash() -> None:
    assert fmt(math.nan, ".1f", " s") == fmt(-math.inf, ".2f", " dB") == fmt(None) == "–"
    assert fmt(1.25, ".1f", " s") == "1.2 s" and fmt(5000.0, ",.0f", " m") == "5,000 m"


def test_rollout_prints_a_dash_where_no_ride_finished(capsys) -> None:
    # three steps of a random taxi deliver nobody: ATT (mean ride time of delivered passengers) is undefined
    argv = ["--scenario", "berlin_random", "--num-taxis", "1", "--episodes", "1", "--time-limit-steps", "3"]
    assert rollout.cli(argv) == 0
    out = capsys.readouterr().out
    assert "ATT –," in out and "nan" not in out and "inf" not in out


def test_an_output_folder_is_created_one_level_deep_at_most(tmp_path: Path) -> None:
    assert output_path(tmp_path / "new" / "x.html", "--out") == tmp_path / "new" / "x.html"
    assert (tmp_path / "new").is_dir()
    with pytest.raises(UsageError, match="nor that folder's parent exists"):
        output_path(tmp_path / "a" / "b" / "x.html", "--out")
    assert not (tmp_path / "a").exists()
    with pytest.raises(UsageError, match="is a folder"):
        output_path(tmp_path / "new", "--out")


def test_trainargs_refuse_every_out_of_range_number() -> None:
    edges = dict(gae_lambda=0.0, ent_coef=0.0, eval_every=0, threads=0, shaping=0.0)
    TrainArgs.from_flat(edges)  # the edges that are allowed
    for bad in [
        {"gamma": 0.0}, {"gamma": 1.01}, {"clip_coef": 0.0}, {"learning_rate": 0.0}, {"num_envs": 0},
        {"num_steps": 0}, {"num_minibatches": 0}, {"update_epochs": 0}, {"max_grad_norm": -1.0}, {"seed": -1},
        {"num_taxis": 0}, {"time_limit_steps": 0}, {"target_kl": 0.0}, {"shaping_gamma": 1.5}, {"max_wall_s": 0.0},
        {"shaping_anneal_frac": 2.0}, {"total_timesteps": 2.5}, {"eval_every": -1}, {"ent_coef": math.inf},
    ]:  # fmt: skip
        with pytest.raises(ValueError, match=f"--{next(iter(bad)).replace('_', '-')}="):
            TrainArgs.from_flat(bad)


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory) -> Path:
    """A one-taxi policy of berlin_random (12 passenger slots), one short iteration."""
    folder = tmp_path_factory.mktemp("runs")
    result = train(tiny_train_args(folder, scenario="berlin_random", num_taxis=1, eval_every=0))
    return result.run_dir / "best.pt"


def test_a_one_taxi_policy_on_a_four_taxi_env_says_what_differs(tiny_checkpoint: Path) -> None:
    policy, _ = load_policy(tiny_checkpoint)
    assert (policy.num_taxis, policy.passenger_slots) == (1, 12)
    obs, _ = uamfleet.vector_env("berlin_random", num_envs=1, num_taxis=4).reset(seed=0)
    with pytest.raises(
        ValueError, match=r"'others' \(3, 3\) \(trained on \(1, 3\)\).*num_taxis=1 and max_passengers=12"
    ):
        policy(obs)
    obs, _ = uamfleet.vector_env("berlin_random", num_envs=2, num_taxis=1).reset(seed=0)
    assert policy(obs).shape == (2, 1)


def test_benchmark_flies_a_checkpoint_beside_a_planner(tiny_checkpoint: Path, tmp_path: Path, capsys) -> None:
    out_md = tmp_path / "results.md"
    argv = ["--count", "1", "--jobs", "1", "--methods", "raster_replan", "--checkpoint", str(tiny_checkpoint),
            "--out-csv", str(tmp_path / "b.csv"), "--out-md", str(out_md)]  # fmt: skip
    assert benchmark.cli(argv) == 0
    rows = benchmark.read_rows(tmp_path / "b.csv")
    assert [r["method"] for r in rows] == ["raster_replan", "learned"]
    assert rows[0]["pr_pct"] == 100.0 and np.isfinite(rows[1]["td_m"])
    table = out_md.read_text(encoding="utf-8")
    assert f"--methods raster_replan --checkpoint {tiny_checkpoint}" in table  # the command that made it
    assert "| learned |" in table and "nan" not in table  # no best_known here: its ratio columns are "–"


def test_benchmark_refuses_a_fleet_checkpoint(tmp_path: Path, capsys) -> None:
    result = train(tiny_train_args(tmp_path, **TINY_FLEET))
    capsys.readouterr()
    assert benchmark.cli(["--count", "1", "--checkpoint", str(result.run_dir / "best.pt")]) == 2
    assert "was trained with 2 taxis; the benchmark's instances have one taxi" in capsys.readouterr().err


def console_scripts() -> dict[str, str]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["scripts"]


def test_every_console_script_resolves_to_a_command() -> None:
    scripts = console_scripts()
    assert {"uamfleet-train", "uamfleet-rollout", "uamfleet-render", "uamfleet-benchmark"} <= set(scripts)
    for name, target in scripts.items():
        module, _, attr = target.partition(":")
        cli = getattr(import_module(module), attr)
        assert callable(cli), name
        assert cli.__defaults__[-1] == name  # its prog: messages name the command the user typed


def test_an_installed_script_runs_from_another_folder(tmp_path: Path) -> None:
    script = Path(sys.executable).parent / "uamfleet-rollout"
    assert script.exists(), f"{script} is missing: reinstall the project (bash scripts/setup.sh)"
    done = subprocess.run([str(script), "--help"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "Fly a policy" in done.stdout and "--scenario" in done.stdout
    bad = subprocess.run([str(script), "--episodes", "0"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and bad.stderr.startswith("uamfleet-rollout: error: --episodes 0")


def test_the_repository_forms_still_run(tmp_path: Path) -> None:
    for argv, prog in ((["-m", "eval.rollout", "--seed", "-5"], "python -m eval.rollout"),
                       (["train/ppo.py", "--gamma", "2"], "train/ppo.py")):  # fmt: skip
        done = subprocess.run([sys.executable, *argv], cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert done.returncode == 2 and done.stderr.startswith(f"{prog}: error: "), done.stderr
        assert done.stderr.count("\n") == 1


def test_the_message_of_tyros_box_in_both_of_its_drawings() -> None:
    from uamfleet.cli._common import _box_message

    framed = "\n".join([
        "╭─ Invalid choice ──────────────────╮",
        "│ invalid choice 'x' for argument   │",
        "│ '--scenario'. Expected one of     │",
        "│ ('a', 'b').                       │",
        "│ ───────────────────────────────── │",
        "│ For full helptext, run p --help   │",
        "╰───────────────────────────────────╯",
    ])  # fmt: skip
    plain = "\n".join([
        " Invalid choice     ",
        " ------------------ ",
        "  invalid choice 'x' for argument",
        "  '--scenario'. Expected one of",
        "  ('a', 'b').",
        "  ------------------",
        "  For full helptext, run p --help",
    ])  # fmt: skip
    expected = "invalid choice 'x' for argument '--scenario'. Expected one of ('a', 'b')."
    assert _box_message(framed) == _box_message(plain) == expected
