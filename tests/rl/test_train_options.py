"""The training options in groups (``uamfleet.rl.options.TrainArgs``): flat in a checkpoint and on the command line,
grouped in code and in ``--help``."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from uamfleet.cli import imitate as imitate_cli
from uamfleet.cli import train as train_cli
from uamfleet.config import ConfigError
from uamfleet.rl.checkpoint import PRETRAINED, Checkpoint, pretrained_path
from uamfleet.rl.imitation import ImitationArgs
from uamfleet.rl.legacy import checkpoint_args
from uamfleet.rl.options import GROUPS, TrainArgs

SECTIONS = {"env": "--scenario", "observer": "--passenger-window", "net": "--d-model", "ppo": "--learning-rate",
            "eval": "--eval-every", "run": "--run-dir"}  # fmt: skip


def test_every_option_lies_in_one_group_and_the_flat_dict_reads_back() -> None:
    names = [f.name for cls in GROUPS.values() for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names)) == 71
    assert list(GROUPS) == ["env", "observer", "net", "ppo", "eval", "run"]
    default = TrainArgs()
    assert set(default.flat()) == set(names) and default.flat()["run_dir"] == "runs"  # plain values
    assert TrainArgs.from_flat(default.flat()) == default
    changed = TrainArgs.from_flat(dict(scenario="berlin_fleet", fleet_mixture=["2x12", "4x24"], thresholds=[-7, -3],
                                       passenger_window=24, learning_rate=3e-4, eval_every=2, run_dir=Path("/tmp/r"),
                                       d_model=32, seed=7))  # fmt: skip
    assert (changed.env.fleet_mixture, changed.env.thresholds) == (("2x12", "4x24"), (-7.0, -3.0))  # lists as tuples
    assert (changed.observer.passenger_window, changed.ppo.learning_rate, changed.net.d_model) == (24, 3e-4, 32)
    assert changed.run.run_dir == Path("/tmp/r") and changed.flat()["run_dir"] == "/tmp/r"
    assert TrainArgs.from_flat(changed.flat()) == changed
    assert changed.with_options(seed=8).ppo.seed == 8 and changed.ppo.seed == 7
    with pytest.raises(dataclasses.FrozenInstanceError):
        changed.ppo.seed = 9  # type: ignore[misc]


def test_a_flat_dict_with_an_unknown_option_is_refused_by_name() -> None:
    with pytest.raises(ConfigError, match=r"\['learning_rat'\] are no options of TrainArgs"):
        TrainArgs.from_flat({"learning_rat": 1e-3})
    with pytest.raises(ConfigError, match=r"--learning-rate=-1\.0 is out of range"):
        TrainArgs.from_flat({"learning_rate": -1.0})  # the checks run on the grouped options


@pytest.mark.parametrize("name", sorted(set(PRETRAINED.values())))
def test_every_shipped_checkpoint_reads_as_grouped_options_and_back(name: str) -> None:
    path = pretrained_path(next(k for k, v in PRETRAINED.items() if v == name))
    saved = Checkpoint.load(path).args
    args = checkpoint_args(Checkpoint.load(path))
    flat = args.flat()
    known = {k: v for k, v in saved.items() if k in flat}
    assert len(known) >= 50
    for key, value in known.items():  # every stored option reads back as stored (a list as the tuple it was)
        assert flat[key] == (tuple(value) if isinstance(value, list) else value), key
    assert args.env.scenario == saved["scenario"] and args.net.variant == saved["variant"]
    assert TrainArgs.from_flat(flat) == args


def test_help_lists_the_flat_flags_in_their_sections(capsys, monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "100")  # one column: the sections one after the other
    with pytest.raises(SystemExit) as done:
        train_cli.cli(["--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    starts = {group: out.index(f"{group} options") for group in SECTIONS}
    assert list(starts.values()) == sorted(starts.values())  # env, observer, net, ppo, eval, run in that order
    ends = [*list(starts.values())[1:], len(out)]
    for (group, flag), end in zip(SECTIONS.items(), ends, strict=True):
        assert flag in out[starts[group] : end], (group, flag)
    assert "--ppo." not in out and "--env." not in out  # the flags keep their names


def test_the_command_line_fills_the_groups(monkeypatch) -> None:
    seen: list[TrainArgs] = []
    monkeypatch.setattr(train_cli, "main", lambda args: seen.append(args) or 0)
    argv = ["--scenario", "berlin_instances", "--learning-rate", "0.0003", "--no-anneal-lr", "--heading-lookahead",
            "--eval-instances", "5", "--run-name", "x", "--thresholds", "-7", "-3"]  # fmt: skip
    assert train_cli.cli(argv) == 0
    (args,) = seen
    assert args.flat() == TrainArgs.from_flat(dict(scenario="berlin_instances", learning_rate=3e-4, anneal_lr=False,
                                            heading_lookahead=True, eval_instances=5, run_name="x",
                                            thresholds=(-7.0, -3.0))).flat()  # fmt: skip


def test_the_imitation_options_share_the_trainers_group_names_and_read_flat(capsys, monkeypatch) -> None:
    groups = [f.name for f in dataclasses.fields(ImitationArgs)]
    assert groups == ["env", "observer", "net", "expert", "fit", "eval", "run"]
    assert ImitationArgs().eval.eval_instances == 50 and ImitationArgs().run.run_name == "berlin_imitation"
    args = ImitationArgs.from_flat(dict(thresholds=[-5, -3], lookahead=True, lookahead_depth=2, expert_beam=8, seed=4))
    assert (args.env.thresholds, args.observer.lookahead_depth, args.expert.expert_beam, args.fit.seed) == (
        (-5.0, -3.0), 2, 8, 4,
    )  # fmt: skip
    assert ImitationArgs.from_flat(args.flat()) == args and len(args.flat()) == 32  # with --also-maps
    with pytest.raises(ConfigError, match="--lookahead-depth=2 is the look-ahead's depth"):
        ImitationArgs.from_flat({"lookahead_depth": 2})
    with pytest.raises(ConfigError, match=r"\['beam'\] are no options of ImitationArgs"):
        ImitationArgs.from_flat({"beam": 2})
    monkeypatch.setenv("COLUMNS", "100")
    with pytest.raises(SystemExit):
        imitate_cli.cli(["--help"])
    out = capsys.readouterr().out
    assert out.index("expert options") < out.index("--expert-beam") < out.index("fit options") < out.index("--epochs")
