"""Checkpoints and runs that are safe: weights_only loading, refusals that say why, run folders that are never
silently overwritten, Ctrl-C and resume that neither lose nor double-count steps, exit status 130."""

from __future__ import annotations

import dataclasses
import io
import os
from pathlib import Path

import numpy as np
import pytest
import torch
from conftest import small_config

import uamfleet
from uamfleet.config import Request
from uamfleet.observe.spec import ObserverSpec, layout_to_dict, observation_layout
from uamfleet.env.vector_env import VectorEnv
from uamfleet.rl.trainer import Checkpoint, TrainArgs, load_policy, read_progress, train, upgrade_checkpoint

ONE_PASSENGER = small_config(requests=(Request(0, (350.0, 150.0), (350.0, 350.0)),), time_limit_steps=30)
BATCH = 16 * 4  # agent-steps per iteration of args()


def args(tmp_path: Path, iterations: int = 2, **overrides) -> TrainArgs:
    base = dict(
        total_timesteps=iterations * BATCH, num_envs=4, num_steps=16, num_minibatches=2, update_epochs=1,
        eval_every=1, checkpoint_every=1, run_dir=tmp_path, run_name="run", progress=False, tensorboard=False,
        threads=1, time_limit_steps=30, eval_time_limit_steps=30, d_model=16, num_heads=2,
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)


def steps(folder: Path) -> list[int]:
    return [int(r["global_step"]) for r in read_progress(folder / "progress.csv")]


def interrupt_in_rollout(monkeypatch, after_calls: int) -> None:
    """Ctrl-C arrives in a rollout: the training env's step (4 envs; evaluations fly 1) raises KeyboardInterrupt
    on call after_calls + 1."""
    real, calls = VectorEnv.step, {"n": 0}

    def step(self, actions):
        calls["n"] += self.num_envs == 4
        if calls["n"] > after_calls:
            raise KeyboardInterrupt
        return real(self, actions)

    monkeypatch.setattr(VectorEnv, "step", step)


def test_checkpoint_loads_with_weights_only_and_holds_plain_values(tmp_path):
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    payload = torch.load(tmp_path / "run" / "last.pt", weights_only=True)
    assert payload["iteration"] == 1 and payload["global_step"] == BATCH
    assert isinstance(payload["numpy_rng"]["keys"], list) and len(payload["numpy_rng"]["keys"]) == 624
    assert payload["obs_shapes"]["action_mask"] == [16]


def test_a_pickle_that_runs_code_is_refused_without_running_it(tmp_path):
    marker = tmp_path / "ran"

    class Exploit:
        def __reduce__(self):
            return (os.system, (f"touch {marker}",))

    path = tmp_path / "evil.pt"
    path.write_bytes(_torch_bytes({"model": Exploit()}))
    with pytest.raises(
        ValueError, match=r"evil.pt is not a checkpoint uamfleet loads safely .*(?i:unsupported global)"
    ):
        load_policy(path, env_config=ONE_PASSENGER)
    assert not marker.exists()


def test_foreign_files_are_refused_with_a_message(tmp_path):
    junk, foreign = tmp_path / "junk.pt", tmp_path / "foreign.pt"
    junk.write_bytes(b"not a checkpoint")
    foreign.write_bytes(_torch_bytes({"state_dict": {"w": torch.zeros(2)}}))
    with pytest.raises(ValueError, match=r"junk.pt is not a checkpoint uamfleet loads safely"):
        load_policy(junk)
    with pytest.raises(ValueError, match=r"foreign.pt is not a uamfleet training checkpoint .*got \['state_dict'\]"):
        load_policy(foreign)
    with pytest.raises(FileNotFoundError, match=r"missing.pt does not exist"):
        load_policy(tmp_path / "missing.pt")


def test_an_old_pickled_checkpoint_is_refused_and_can_be_upgraded(tmp_path):
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    path = tmp_path / "run" / "last.pt"
    old = torch.load(path, weights_only=True)  # rewrite it as format 1 did: NumPy objects pickled inside
    old["numpy_rng"] = np.random.get_state()
    old["obs_normalizer"] = {k: {"mean": v["mean"].numpy(), "var": v["var"].numpy(), "count": np.float64(v["count"])}
                             for k, v in old["obs_normalizer"].items()}  # fmt: skip
    old["args"] = {**old["args"], "scenario": "berlin_p4"}  # upgrade needs a named scenario for the obs layout
    for key in ("obs_shapes", "format", "cuda_rng", "obs_layout", "observer", "world"):
        old.pop(key, None)
    path.write_bytes(_torch_bytes(old))
    with pytest.raises(ValueError, match=r"numpy.*upgrade_checkpoint"):
        Checkpoint.load(path)
    upgrade_checkpoint(path)
    assert Checkpoint.load(path).numpy_rng["name"] == "MT19937"
    upgraded = torch.load(path, weights_only=True)  # the current format: what it reads and its world stored
    assert upgraded["format"] == 3 and upgraded["world"]["scenario"] == "berlin_p4"
    assert ObserverSpec.from_dict(upgraded["observer"]) == ObserverSpec(slots_per_taxi=4.0, time_scale_steps=30)


def test_resume_with_another_architecture_or_layout_names_what_differs(tmp_path):
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    more = dict(iterations=2, resume=True)
    with pytest.raises(ValueError, match=r"variant: checkpoint 'de_msfea', this run 'le'.*d_model: checkpoint 16"):
        train(args(tmp_path, variant="le", d_model=32, **more), env_config=ONE_PASSENGER)
    bigger = dataclasses.replace(ONE_PASSENGER, patch_size=6)
    with pytest.raises(ValueError, match=r"observation field 'sinr_patch': checkpoint shape \[4, 4\], this env"):
        train(args(tmp_path, **more), env_config=bigger)
    with pytest.raises(ValueError, match=r"observation field 'sinr_patch'"):
        load_policy(tmp_path / "run" / "last.pt", env_config=bigger)


def test_a_checkpoint_stores_its_spec_and_resume_names_a_field_that_means_something_else(tmp_path):
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    path = tmp_path / "run" / "last.pt"
    ckpt = Checkpoint.load(path)
    assert ckpt.obs_layout == layout_to_dict(observation_layout(ONE_PASSENGER))
    # same shapes, another meaning (as if the bounds of 'self' had changed since): resume refuses and names it
    ckpt.obs_layout = {**ckpt.obs_layout, "self": {**ckpt.obs_layout["self"], "high": 9.0}}
    ckpt.save(path)
    with pytest.raises(ValueError, match=r"observation field 'self': high 9.0 vs 1.0 \(checkpoint vs this env\)"):
        train(args(tmp_path, iterations=2, resume=True), env_config=ONE_PASSENGER)


def test_an_existing_run_is_not_overwritten_without_overwrite(tmp_path):
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    before = (tmp_path / "run" / "progress.csv").read_text()
    with pytest.raises(FileExistsError, match=r"run already holds a run .*--resume.*--overwrite"):
        train(args(tmp_path, iterations=2), env_config=ONE_PASSENGER)
    assert (tmp_path / "run" / "progress.csv").read_text() == before
    again = train(args(tmp_path, iterations=2, seed=9, overwrite=True), env_config=ONE_PASSENGER)
    assert again.iterations == 2 and steps(tmp_path / "run") == [BATCH, 2 * BATCH]


@pytest.mark.parametrize("name", ["../../x", "a/b", "..", ".hidden", "/abs"])
def test_run_names_cannot_leave_the_run_folder(tmp_path, name):
    with pytest.raises(ValueError, match="must be one folder name"):
        train(args(tmp_path / "runs", run_name=name), env_config=ONE_PASSENGER)
    assert not (tmp_path / "x").exists() and list(tmp_path.iterdir()) == []


def test_ctrl_c_saves_the_last_finished_iteration_and_resume_counts_no_untrained_step(tmp_path, monkeypatch):
    # iteration = 16 env steps; Ctrl-C in the 3rd rollout, after 2 full iterations and 5 steps
    interrupt_in_rollout(monkeypatch, after_calls=2 * 16 + 5)
    cut = train(args(tmp_path, iterations=4, tensorboard=True), env_config=ONE_PASSENGER)
    assert cut.interrupted and cut.global_step == 2 * BATCH and cut.iterations == 2
    assert Checkpoint.load(tmp_path / "run" / "last.pt").global_step == 2 * BATCH
    monkeypatch.undo()
    done = train(args(tmp_path, iterations=4, tensorboard=True, resume=True), env_config=ONE_PASSENGER)
    assert not done.interrupted and done.global_step == 4 * BATCH
    assert steps(tmp_path / "run") == [BATCH, 2 * BATCH, 3 * BATCH, 4 * BATCH]
    assert _tensorboard_steps(tmp_path / "run") == [BATCH, 2 * BATCH, 3 * BATCH, 4 * BATCH]


def test_rows_logged_after_the_checkpoint_are_trained_again_not_duplicated(tmp_path):
    train(args(tmp_path, iterations=3, checkpoint_every=2, tensorboard=True), env_config=ONE_PASSENGER)
    path = tmp_path / "run" / "last.pt"
    ckpt = Checkpoint.load(path)  # as if killed hard after iteration 3 was logged and the last save was iteration 2
    ckpt.iteration, ckpt.global_step = 2, 2 * BATCH
    ckpt.save(path)
    train(args(tmp_path, iterations=3, tensorboard=True, resume=True), env_config=ONE_PASSENGER)
    assert steps(tmp_path / "run") == [BATCH, 2 * BATCH, 3 * BATCH]
    assert _tensorboard_steps(tmp_path / "run") == [BATCH, 2 * BATCH, 3 * BATCH]


def test_resuming_a_finished_run_says_so_and_keeps_its_last_point(tmp_path, capsys):
    train(args(tmp_path, iterations=2, tensorboard=True), env_config=ONE_PASSENGER)
    capsys.readouterr()
    again = train(args(tmp_path, iterations=2, tensorboard=True, resume=True), env_config=ONE_PASSENGER)
    assert "is finished (2 of 2 iterations" in capsys.readouterr().out
    assert again.global_step == 2 * BATCH and again.iterations == 2
    assert _tensorboard_steps(tmp_path / "run") == [BATCH, 2 * BATCH]


def test_the_command_line_exits_130_after_ctrl_c(tmp_path, monkeypatch):
    import uamfleet.cli.train as cli  # what train/ppo.py and uamfleet-train run

    monkeypatch.setattr(cli, "train", lambda a: train(a, env_config=ONE_PASSENGER))
    interrupt_in_rollout(monkeypatch, after_calls=20)
    assert cli.main(args(tmp_path)) == 130
    assert (tmp_path / "run" / "last.pt").exists()


def test_the_policy_of_a_checkpoint_flies(tmp_path):
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    policy, saved = load_policy(tmp_path / "run" / "best.pt", env_config=ONE_PASSENGER)
    obs, _ = uamfleet.VectorEnv(ONE_PASSENGER).reset(seed=0)
    assert saved.env.num_envs == 4 and policy(obs).shape == (1, 1)


def _torch_bytes(obj) -> bytes:
    data = io.BytesIO()
    torch.save(obj, data)
    return data.getvalue()


def _tensorboard_steps(folder: Path) -> list[int]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(folder / "tb"))
    acc.Reload()
    return [e.step for e in acc.Scalars("losses/value_loss")]
