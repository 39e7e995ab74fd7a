"""Where one PPO iteration of the generalist's recipe spends its time: thread CPU seconds per part of the rollout
(env step, observation normaliser, network forward, the rest) and of the update (minibatch assembly, forward,
backward, gradient clipping + Adam, the rest), then forward and backward per network module at the update's
minibatch size. With one thread (the default) the main thread's CPU time is all the work, which other processes'
load on a shared machine barely changes, unlike wall time. ``--baseline`` runs another checkout the same way, in
turn with this one, and prints the speed-up pair by pair.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/ppo_profile.py                      # berlin_stops' recipe
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/ppo_profile.py --heading-lookahead  # + the look-ahead (berlin)
    .venv/bin/python benchmarks/ppo_profile.py --baseline /tmp/before --pairs 3        # before / after, in turn

The recipe is the generalist's: ``berlin_instances``, thresholds -7 ... -3 dB, ``--action-head
stops``, ``de_msfea``, d_model 32, 60 envs x 128 steps, 8 minibatches x 4 epochs (7,680 agent-steps per iteration).
The first iteration (numba compilation, allocations) is warm-up and not counted. Module times come from forward
hooks and full backward hooks (the time between a module's backward pre-hook and its backward hook), on
``--module-batches`` minibatches whose observation requires gradients (else a module fed by the observation alone
reports no backward; this adds the input gradients of the first layers, a small cost); "rest" is what no listed
module covers (masks, concatenations, the distribution, the loss).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from uamfleet.cli._common import run as run_cli
from uamfleet.rl import collector, trainer
from uamfleet.rl import learner as learner_room
from uamfleet.rl.distributed import Ranks
from uamfleet.rl import networks
from uamfleet.rl.networks import MSHAActorCritic, obs_to_torch
from uamfleet.rl.trainer import TrainArgs


@dataclass
class Args:
    heading_lookahead: bool = False
    """the look-ahead input as well (EnvConfig.heading_lookahead)"""
    iterations: int = 3
    """PPO iterations (the first is warm-up and not counted)"""
    num_envs: int = 60
    """the recipe's 60 envs (12 per threshold)"""
    num_steps: int = 128
    num_minibatches: int = 8
    """of the 4 update epochs (the trainer's default)"""
    module_batches: int = 16
    """minibatches timed module by module (0: none)"""
    interleaved: int = 0
    """rounds of the interleaved network checks (the map CNNs paired or not, no_grad or inference_mode; 0: none)"""
    threads: int = 1
    """torch CPU threads"""
    baseline: Path | None = None
    """another checkout's root (e.g. ``git worktree add /tmp/before <commit>``): measure it and this one in turn"""
    pairs: int = 3
    """with --baseline: how many (baseline, this) pairs"""
    json_out: Path | None = None
    """write the figures here as JSON instead of printing them (what --baseline's runs do)"""


def recipe(args: Args, run_dir: Path) -> TrainArgs:
    """The generalist's training options, one thread, nothing logged."""
    return TrainArgs.from_flat(dict(
        scenario="berlin_instances", thresholds=(-7, -6, -5, -4, -3), action_head="stops", variant="de_msfea",
        d_model=32, num_envs=args.num_envs, num_steps=args.num_steps, num_minibatches=args.num_minibatches,
        gamma=0.995, gae_lambda=0.95, learning_rate=1e-4, ent_coef=0.0, shaping=0.0, time_limit_steps=600,
        total_timesteps=10**9, eval_every=0, checkpoint_every=10**9, run_dir=run_dir, run_name="profile",
        progress=False, tensorboard=False, threads=1, heading_lookahead=args.heading_lookahead,
    ))  # fmt: skip


class Clock:
    """Thread CPU seconds per named part; :meth:`wrap` times every call of a function."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    @contextmanager
    def part(self, name: str) -> Iterator[None]:
        begin = time.thread_time()
        try:
            yield
        finally:
            self.seconds[name] += time.thread_time() - begin

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*a: Any, **kw: Any) -> Any:
            with self.part(name):
                return fn(*a, **kw)

        return timed


@contextmanager
def patched(obj: Any, name: str, value: Any) -> Iterator[None]:
    old = getattr(obj, name)
    setattr(obj, name, value)
    try:
        yield
    finally:
        setattr(obj, name, old)


def phase_profile(run: collector.Run, learner: learner_room.Learner, iterations: int) -> dict[str, float]:
    """Per part, thread CPU seconds summed over ``iterations`` iterations of the training loop after one warm-up;
    also "cpu" (the process's CPU seconds, every thread) and "wall" of the timed iterations."""
    clock = Clock()
    net, buf = learner.net, run.buffer
    backward, clip = torch.Tensor.backward, torch.nn.utils.clip_grad_norm_
    with (
        patched(run.venv, "step", clock.wrap("rollout: env step", run.venv.step)),
        patched(collector, "normalise", clock.wrap("rollout: normaliser", collector.normalise)),
        patched(learner_room, "normalise", clock.wrap("rollout: normaliser", learner_room.normalise)),
        patched(net, "forward", clock.wrap("rollout: network forward", net.forward)),
        patched(buf, "minibatch", clock.wrap("update: minibatch assembly", buf.minibatch)),
        patched(net, "policy_and_value", clock.wrap("update: forward", net.policy_and_value)),
        patched(torch.Tensor, "backward", clock.wrap("update: backward", backward)),
        patched(torch.nn.utils, "clip_grad_norm_", clock.wrap("update: clip + Adam", clip)),
        patched(learner.optimizer, "step", clock.wrap("update: clip + Adam", learner.optimizer.step)),
    ):
        for i in range(iterations + 1):
            if i == 1:  # the first was warm-up
                clock.seconds.clear()
                cpu, wall = time.process_time(), time.perf_counter()
            with clock.part("rollout"):  # the rollout and GAE's one forward (counted as network forward)
                collector.collect_rollout(run, net, learner.normalizer, learner.scaler)
                advantages, returns = learner_room.compute_advantages(run, learner)
            with clock.part("update"):  # the update's forward is policy_and_value, not net.forward
                learner_room.ppo_update(run, learner, advantages, returns)
    seconds = dict(clock.seconds)
    seconds["rollout: network forward"] -= seconds.get("update: forward", 0.0)  # net.forward inside it
    return seconds | {"cpu": time.process_time() - cpu, "wall": time.perf_counter() - wall}


def timed_modules(net: MSHAActorCritic) -> dict[str, nn.Module]:
    """The network's parts worth a row: the torso's encoders and the heads."""
    parts = {f"torso.{name}": m for name, m in net.torso.named_children()}
    parts |= {"actor": net.actor, "critic": net.critic}
    if net.stop_head is not None:
        parts["stop_head"] = net.stop_head
    return parts


def module_profile(
    run: collector.Run, learner: learner_room.Learner, batches: int
) -> tuple[dict[str, list[float]], float]:
    """{module: [forward s, backward s]} and the whole forward + backward's seconds, over ``batches`` minibatches
    of the update's size (the loss: the PPO loss's ingredients summed, enough to reach every parameter)."""
    net, buf = learner.net, run.buffer
    size = run.batch_size // run.args.ppo.num_minibatches
    times: dict[str, list[float]] = {name: [0.0, 0.0] for name in timed_modules(net)}
    starts: dict[str, float] = {}
    handles = []
    for name, module in timed_modules(net).items():

        def pre(_m: nn.Module, _inp: Any, name: str = name) -> None:
            starts[name] = time.thread_time()

        def post(_m: nn.Module, _inp: Any, _out: Any, name: str = name) -> None:
            times[name][0] += time.thread_time() - starts[name]

        def back_pre(_m: nn.Module, _grad: Any, name: str = name) -> None:
            starts["b" + name] = time.thread_time()

        def back(_m: nn.Module, _gi: Any, _go: Any, name: str = name) -> None:
            times[name][1] += time.thread_time() - starts["b" + name]

        handles += [module.register_forward_pre_hook(pre), module.register_forward_hook(post)]
        handles += [module.register_full_backward_pre_hook(back_pre), module.register_full_backward_hook(back)]
    # The two map CNNs run as one function (networks.paired_map_features), not through their modules: time its
    # forward here; its backward has no hook and falls in "rest".
    # (A checkout from before it has none, and its map CNNs are timed as modules.)
    paired = getattr(networks, "paired_map_features", None)
    if paired is not None:
        times["map CNNs, paired (forward only)"] = [0.0, 0.0]

        def timed_maps(*a: Any) -> torch.Tensor:
            begin = time.thread_time()
            out = paired(*a)
            times["map CNNs, paired (forward only)"][0] += time.thread_time() - begin
            return out

        setattr(networks, "paired_map_features", timed_maps)  # noqa: B010 (mypy: another signature)
    rng = np.random.default_rng(0)
    total = 0.0
    try:
        for _ in range(batches):
            obs, state, actions, _ = buf.minibatch(rng.choice(run.batch_size, size, replace=False), run.device)
            for x in obs.values():  # else a module fed by the observation alone reports no backward
                x.requires_grad_()
            begin = time.thread_time()
            _, logprob, entropy, value = net.get_action_and_value(obs, actions, state=state)
            (logprob.sum() + entropy.sum() + value.sum()).backward()
            total += time.thread_time() - begin
            net.zero_grad()
    finally:
        if paired is not None:
            networks.paired_map_features = paired
        for handle in handles:
            handle.remove()
    return times, total


def plain_maps(first: nn.Module, second: nn.Module, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """The map CNNs as before the paired convolution: one call each."""
    return torch.cat([first(a), second(b)], dim=-1)


def interleaved_network_checks(
    run: collector.Run, learner: learner_room.Learner, rounds: int
) -> dict[str, list[float]]:
    """Thread CPU ms per call of each variant of one computation, variants alternating call by call on the same
    data (so drift in the machine's speed hits both alike): the update's forward + backward (minibatch of the
    update's size) with the map CNNs paired or one by one, and the rollout's forward (one step's agents) with the
    map CNNs paired or not, under no_grad or inference_mode."""
    net, buf = learner.net, run.buffer
    size = run.batch_size // run.args.ppo.num_minibatches
    rng = np.random.default_rng(1)
    batches = [buf.minibatch(rng.choice(run.batch_size, size, replace=False), run.device) for _ in range(4)]
    steps = [obs_to_torch({k: v[t] for k, v in buf.obs.items()}, run.device) for t in range(8)]

    def update_step(i: int) -> None:
        obs, state, actions, _ = batches[i % len(batches)]
        _, logprob, entropy, value = net.get_action_and_value(obs, actions, state=state)
        (logprob.sum() + entropy.sum() + value.sum()).backward()
        net.zero_grad()

    def rollout_step(i: int, mode: Callable[[], Any]) -> None:
        with mode():
            net(steps[i % len(steps)])

    variants: dict[str, tuple[Callable[[int], None], bool]] = {
        "update fwd+bwd, maps one by one": (update_step, False),
        "update fwd+bwd, maps paired": (update_step, True),
        "rollout fwd, no_grad, maps one by one": (lambda i: rollout_step(i, torch.no_grad), False),
        "rollout fwd, inference_mode, maps one by one": (lambda i: rollout_step(i, torch.inference_mode), False),
        "rollout fwd, inference_mode, maps paired": (lambda i: rollout_step(i, torch.inference_mode), True),
    }
    paired = networks.paired_map_features
    times: dict[str, list[float]] = {name: [] for name in variants}
    for i in range(rounds + 2):  # two warm-up rounds
        for name, (fn, pair) in variants.items():
            networks.paired_map_features = paired if pair else plain_maps
            begin = time.thread_time()
            fn(i)
            if i >= 2:
                times[name].append((time.thread_time() - begin) * 1e3)
    networks.paired_map_features = paired
    return times


def measure(args: Args) -> dict[str, Any]:
    """Build the recipe's run in this process, profile its iterations (and modules); the figures as a dict."""
    torch.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory() as tmp:
        run = collector.make_run(recipe(args, Path(tmp)), None, *Ranks.from_env("cpu", "gloo"))
        learner = learner_room.make_learner(run)
        trainer.start(run, learner, None)
        phases = phase_profile(run, learner, args.iterations - 1)
        modules, whole = module_profile(run, learner, args.module_batches) if args.module_batches else ({}, 0.0)
        checks = interleaved_network_checks(run, learner, args.interleaved) if args.interleaved else {}
    return {"phases": phases, "iterations": args.iterations - 1, "agent_steps": run.batch_size, "modules": modules,
            "whole": whole, "interleaved": checks}  # fmt: skip


def report(args: Args, result: dict[str, Any]) -> None:
    phases, n, steps = dict(result["phases"]), result["iterations"], result["agent_steps"]
    print(f"generalist recipe{' + look-ahead' if args.heading_lookahead else ''}: {steps:,} agent-steps per "
          f"iteration, {args.threads} thread(s); main thread's CPU s per iteration (mean of {n})")  # fmt: skip
    for phase in ("rollout", "update"):
        total = phases[phase]
        print(f"{phase + (' (+ GAE)' if phase == 'rollout' else ''):<32} {total / n:>7.3f} s")
        parts = {k.split(": ", 1)[1]: v for k, v in phases.items() if k.startswith(phase + ":")}
        for name, seconds in parts.items():
            print(f"  {name:<30} {seconds / n:>7.3f} s")
        print(f"  {'rest':<30} {(total - sum(parts.values())) / n:>7.3f} s")
    print(f"process CPU {phases['cpu'] / n:.3f} s, wall {phases['wall'] / n:.3f} s per iteration: "
          f"{steps * n / phases['cpu']:,.0f} agent-steps per CPU second, "
          f"{steps * n / phases['wall']:,.0f} per wall second")  # fmt: skip
    if result["interleaved"]:
        print(f"\ninterleaved, thread CPU ms per call: median (quartiles) of {args.interleaved}")
        for name, ms in result["interleaved"].items():
            q1, q2, q3 = np.percentile(ms, [25, 50, 75])
            print(f"  {name:<46} {q2:>7.2f} ({q1:.2f}-{q3:.2f})")
    if not result["modules"]:
        return
    per = args.module_batches
    print(f"\nper minibatch of {steps // args.num_minibatches} samples (ms, mean of {per}): forward, backward")
    for name, (fwd, bwd) in sorted(result["modules"].items(), key=lambda kv: -sum(kv[1])):
        if fwd == bwd == 0.0:  # not called as a module (the map CNNs, paired)
            continue
        print(f"  {name:<30} {fwd / per * 1e3:>7.2f} {bwd / per * 1e3:>8.2f}")
    covered = sum(sum(v) for v in result["modules"].values())
    print(f"  {'rest':<30} {(result['whole'] - covered) / per * 1e3:>16.2f}")
    print(f"  {'whole forward + backward':<30} {result['whole'] / per * 1e3:>16.2f}")


def side_by_side(args: Args) -> list[dict[str, Any]]:
    """This checkout and ``args.baseline`` in turn, ``args.pairs`` times, each run a fresh process that imports
    ``uamfleet`` from its checkout; per pair the ratio of CPU seconds per iteration (baseline / this: the speed-up)."""
    assert args.baseline is not None
    here = Path(__file__).resolve().parents[1]
    rows: list[dict[str, Any]] = []
    print(f"side by side: this checkout ({here}) and the baseline ({args.baseline}), {args.pairs} pair(s), "
          f"{args.iterations - 1} timed iteration(s) each, {args.threads} thread(s)")  # fmt: skip
    print(f"{'pair':>4} {'side':<9} {'rollout s':>10} {'update s':>9} {'CPU s/it':>9} {'wall s/it':>10} "
          f"{'steps/CPU s':>12} {'speed-up':>9}")  # fmt: skip
    for pair in range(args.pairs):
        cpu: dict[str, float] = {}
        for side, root in (("baseline", args.baseline.resolve()), ("this", here)):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "result.json"
                command = [sys.executable, str(Path(__file__).resolve()), "--iterations", str(args.iterations),
                           "--threads", str(args.threads), "--module-batches", "0", "--json-out", str(out)]  # fmt: skip
                if args.heading_lookahead:
                    command.append("--heading-lookahead")
                env = os.environ | {"PYTHONPATH": str(root), "OMP_NUM_THREADS": str(args.threads)}
                subprocess.run(command, check=True, cwd=tmp, env=env, stdout=subprocess.DEVNULL)
                result = json.loads(out.read_text())
            phases, n, steps = result["phases"], result["iterations"], result["agent_steps"]
            cpu[side] = phases["cpu"] / n
            speedup = f"{cpu['baseline'] / cpu[side]:.2f}x" if side == "this" else ""
            print(f"{pair + 1:>4} {side:<9} {phases['rollout'] / n:>10.3f} {phases['update'] / n:>9.3f} "
                  f"{cpu[side]:>9.3f} {phases['wall'] / n:>10.3f} {steps / cpu[side]:>12,.0f} {speedup:>9}",
                  flush=True)  # fmt: skip
            rows.append({"pair": pair + 1, "side": side, **result})
    ratios = sorted(r0["phases"]["cpu"] / r1["phases"]["cpu"] for r0, r1 in zip(rows[::2], rows[1::2], strict=True))
    print(f"speed-up (baseline CPU s / this), median of {len(ratios)} pair(s): {statistics.median(ratios):.2f}x "
          f"(range {ratios[0]:.2f}-{ratios[-1]:.2f})")  # fmt: skip
    return rows


def main(args: Args) -> Any:
    if args.iterations < 2:
        raise ValueError(f"iterations={args.iterations}: need >= 2 (the first is warm-up)")
    if args.baseline is not None:
        if not (args.baseline / "uamfleet" / "__init__.py").is_file():
            raise ValueError(f"--baseline {args.baseline} holds no uamfleet package; give a checkout's root folder.")
        return side_by_side(args)
    result = measure(args)
    if args.json_out is not None:
        args.json_out.write_text(json.dumps(result))
        return None
    report(args, result)
    return result


if __name__ == "__main__":
    raise SystemExit(run_cli(main, Args, None, "benchmarks/ppo_profile.py", __doc__))
