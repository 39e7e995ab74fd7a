"""Data-parallel PPO on torch.distributed (gloo, CPU): ranks stay identical, and 2 ranks x E/2 envs make the
same first update as 1 rank x E envs (uamfleet.rl.distributed explains why they must)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.distributed as dist
from conftest import small_config
from torch.distributions import Categorical

from uamfleet.config import Request
from uamfleet.rl.buffer import ObservationNormalizer, RewardScaler, RunningMeanStd
from uamfleet.rl.distributed import World, free_port, launch_local, sample_actions
from uamfleet.rl.trainer import TrainArgs, train

# two taxis per env, so a rank's agents are a slice of [env, taxi] pairs; episodes are truncated (time limit 12 <
# 32 steps) so final-value bootstrapping runs; reward and observation normalisers on (the defaults)
TWO_TAXIS = small_config(
    starts_m=((150.0, 150.0), (250.0, 350.0)),
    requests=(Request(0, (350.0, 150.0), (350.0, 350.0)), Request(2, (150.0, 350.0), (350.0, 250.0))),
    time_limit_steps=12,
)
NUM_ENVS = 4


def args_for(run_dir: Path, iterations: int, resume: bool = False) -> TrainArgs:
    return TrainArgs.from_flat(dict(
        resume=resume,
        total_timesteps=iterations * 32 * NUM_ENVS * 2, num_envs=NUM_ENVS, num_steps=32, num_minibatches=4,
        update_epochs=2, eval_every=0, checkpoint_every=1, run_dir=run_dir, run_name="dp", progress=False,
        tensorboard=False, threads=1, time_limit_steps=12, d_model=16, num_heads=2, seed=5, device="cpu",
    ))  # fmt: skip


def _flat_params(net: torch.nn.Module) -> torch.Tensor:
    return torch.cat([p.detach().reshape(-1).clone() for p in net.parameters()])


def _worker(run_dir: str, iterations: int, out: str, resume: bool = False) -> None:
    params: list[torch.Tensor] = []
    seen: list[int] = []

    def record(iteration: int, net: torch.nn.Module) -> None:
        seen.append(iteration)
        params.append(_flat_params(net))

    result = train(args_for(Path(run_dir), iterations, resume), TWO_TAXIS, on_iteration=record)
    torch.save({"params": params, "losses": result.losses, "iterations": seen}, f"{out}_rank{result.rank}.pt")


def _in_this_process_as_a_world_of_one(fn, *args) -> None:
    """torchrun --nproc_per_node=1, without starting a process (saves an interpreter start-up in the suite)."""
    env = {"RANK": "0", "WORLD_SIZE": "1", "LOCAL_RANK": "0", "LOCAL_WORLD_SIZE": "1", "MASTER_ADDR": "127.0.0.1",
           "MASTER_PORT": str(free_port())}  # fmt: skip
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        fn(*args)
    finally:
        if dist.is_initialized():
            dist.destroy_process_group()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key)
            else:
                os.environ[key] = value


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("dp")
    launch_local(2, _worker, str(tmp / "two"), 2, str(tmp / "two"))
    launch_local(2, _worker, str(tmp / "two"), 3, str(tmp / "resumed"), True)  # every rank resumes from last.pt
    _in_this_process_as_a_world_of_one(_worker, str(tmp / "one"), 1, str(tmp / "one"))
    plain: list[torch.Tensor] = []
    result = train(args_for(tmp / "plain", 1), TWO_TAXIS, on_iteration=lambda _, net: plain.append(_flat_params(net)))
    load = lambda name: torch.load(tmp / f"{name}.pt", weights_only=True)  # noqa: E731
    return {"two": [load("two_rank0"), load("two_rank1")], "one": load("one_rank0"),
            "resumed": [load("resumed_rank0"), load("resumed_rank1")],
            "plain": {"params": plain, "losses": result.losses}, "tmp": tmp}  # fmt: skip


def test_ranks_hold_identical_weights_after_every_update(runs):
    rank0, rank1 = runs["two"]
    assert len(rank0["params"]) == len(rank1["params"]) == 2
    for a, b in zip(rank0["params"], rank1["params"], strict=True):
        assert torch.equal(a, b)
    assert len(rank0["losses"]) == 2 and rank1["losses"] == []  # only rank 0 logs
    assert not torch.equal(rank0["params"][0], rank0["params"][1])  # and the updates did change the weights


def test_every_rank_resumes_from_rank_0s_checkpoint(runs):
    rank0, rank1 = runs["resumed"]
    assert rank0["iterations"] == rank1["iterations"] == [2]  # both continued after iteration 2
    assert torch.equal(rank0["params"][0], rank1["params"][0])
    assert not torch.equal(rank0["params"][0], runs["two"][0]["params"][1])
    assert len(rank0["losses"]) == 3  # the CSV rows before the resume, and one more


def test_two_ranks_make_the_first_update_of_one_rank_with_all_envs(runs):
    two, one, plain = runs["two"][0], runs["one"], runs["plain"]
    initial_change = (one["params"][0] - plain["params"][0]).abs().max()
    torch.testing.assert_close(two["params"][0], one["params"][0], rtol=0, atol=1e-5)
    torch.testing.assert_close(one["params"][0], plain["params"][0], rtol=0, atol=1e-5)  # torchrun with 1 = plain
    for key, value in one["losses"][0].items():
        assert two["losses"][0][key] == pytest.approx(value, rel=1e-4, abs=1e-6), key
        assert plain["losses"][0][key] == pytest.approx(value, rel=1e-4, abs=1e-6), key
    assert initial_change < 1e-5


def test_only_rank_0_writes_the_run(runs):
    folder = runs["tmp"] / "two" / "dp"
    assert sorted(p.name for p in folder.iterdir()) == ["best.pt", "last.pt", "progress.csv"]
    assert [line.split(",")[:2] for line in (folder / "progress.csv").read_text().splitlines()[1:]] == [
        ["1", "256"], ["2", "512"], ["3", "768"]]  # fmt: skip


def test_sampler_is_categorical_sampling_draw_for_draw():
    logits = torch.randn(64, 16) * 3
    logits[:10, :5] = -1e9  # masked headings
    torch.manual_seed(7)
    expected = Categorical(logits=logits).sample()
    after = torch.get_rng_state()
    torch.manual_seed(7)
    assert torch.equal(sample_actions(logits, 0, 64), expected)
    assert torch.equal(torch.get_rng_state(), after)
    torch.manual_seed(7)  # two ranks' shares of the same draw
    top = sample_actions(logits[:32], 0, 64)
    torch.manual_seed(7)
    assert torch.equal(torch.cat([top, sample_actions(logits[32:], 32, 64)]), expected)


def test_shard_needs_a_divisible_env_count():
    assert World(rank=1, world_size=2).shard(8) == (4, 4)
    with pytest.raises(ValueError, match=r"num_envs=5 .* 2 ranks"):
        World(rank=0, world_size=2).shard(5)


class _FakeWorld(World):
    """Two ranks' batches summed in one process: all_sum adds the other rank's contribution."""

    def all_sum(self, x):  # type: ignore[override]
        return np.asarray(x, dtype=np.float64) + self.other  # type: ignore[attr-defined]


def test_pooled_normaliser_moments_equal_the_moments_of_the_joined_batch():
    rng = np.random.default_rng(0)
    a, b = rng.normal(500.0, 30.0, size=(6, 3)), rng.normal(520.0, 10.0, size=(10, 3))
    joined = RunningMeanStd((3,))
    joined.update(np.concatenate([a, b]))
    norm = ObservationNormalizer({"self": (3,), "action_mask": (3,)})  # a feature and a mask (their kinds)
    # rank 0's view: its own batch a, plus rank 1's shifted count / sums (the running mean is 0 on both)
    other = np.concatenate([[len(b)], b.sum(0), (b * b).sum(0)])
    world = _FakeWorld(active=True)
    object.__setattr__(world, "other", other)
    norm.update({"self": a, "action_mask": np.ones((6, 3))}, world)
    np.testing.assert_allclose(norm.fields["self"].mean, joined.mean, rtol=1e-12)
    np.testing.assert_allclose(norm.fields["self"].var, joined.var, rtol=1e-9)
    assert norm.fields["self"].count == pytest.approx(joined.count)


def test_rollout_reward_scaling_in_one_all_reduce_equals_scaling_step_by_step():
    rng = np.random.default_rng(2)
    rewards, done = rng.normal(1.0, 3.0, size=(20, 6)), rng.random((20, 6)) < 0.1
    stepwise, batched = RewardScaler(6, 0.9), RewardScaler(6, 0.9)
    expected = np.stack([stepwise(rewards[t], done[t]) for t in range(20)])
    world = _FakeWorld(active=True)
    object.__setattr__(world, "other", 0.0)  # a world of one rank
    np.testing.assert_allclose(batched.scale_rollout(rewards, done, world), expected, rtol=1e-10)
    np.testing.assert_allclose(batched.rms.var, stepwise.rms.var, rtol=1e-10)
    np.testing.assert_array_equal(batched.returns, stepwise.returns)


def test_without_torchrun_the_world_is_one_plain_process(monkeypatch):
    for key in ("RANK", "WORLD_SIZE"):
        monkeypatch.delenv(key, raising=False)
    world, device = World.from_env("cpu")
    assert (world.active, world.rank, world.world_size, device.type) == (False, 0, 1, "cpu")
    monkeypatch.setenv("RANK", "0")
    monkeypatch.setenv("WORLD_SIZE", "2")
    with pytest.raises(ValueError, match=r"backend='nccl' needs --device cuda"):
        World.from_env("cpu", backend="nccl")
