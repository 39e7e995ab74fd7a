"""Pretrained policies shipped inside the package (the model zoo): one call gives a planner for a user's own instance.

    import uamfleet
    planner = uamfleet.pretrained("berlin")            # the Berlin generalist (one taxi, -7 ... -3 dB)
    cfg = uamfleet.make_config("berlin_p4", sinr_min_db=-5.0)   # or any start / requests / threshold
    traj = planner.fly(cfg)     # one episode; score it with uamfleet.metrics.episode_metrics(traj, cfg.radio)

Each file is a training checkpoint stripped of its optimiser and RNG state (:func:`export_policy`), loaded with
``torch.load(weights_only=True)`` like every checkpoint. The command that trained each, and its held-out
results, are in ``docs/results.md`` ("One learned planner for every instance").
"""

from __future__ import annotations

from pathlib import Path

from uamfleet.rl.checkpoint import PRETRAINED, Checkpoint, pretrained_path
from uamfleet.rl.policy import GreedyPolicy, load_policy


def pretrained(name: str = "berlin", device: str = "cpu") -> GreedyPolicy:
    """The shipped policy ``name`` (:data:`PRETRAINED`) as a greedy planner: call it on observations, or
    ``.fly(cfg)`` any config of its map (``.layout(cfg)`` fits the passenger axis and features to it). Flown at a
    threshold outside those it trained on (its training arguments' ``thresholds``, else ``sinr_min_db``), it
    warns once."""
    policy, args = load_policy(pretrained_path(name), device=device)
    assert policy.trained_on is not None  # load_policy always sets it
    single = args.env.sinr_min_db if args.env.sinr_min_db is not None else policy.trained_on.sinr_min_db
    trained = [float(t) for t in args.env.thresholds] if args.env.thresholds else [float(single)]
    policy.thresholds_db = (min(trained), max(trained))
    return policy


def export_policy(checkpoint: str | Path, out: str | Path) -> Path:
    """Write ``checkpoint`` without what only training needs (optimiser moments, RNG states): a few hundred
    kB that still loads with :func:`uamfleet.rl.policy.load_policy` (it cannot be resumed)."""
    ckpt = Checkpoint.load(checkpoint)
    ckpt.optimizer = {}
    ckpt.numpy_rng = {}
    ckpt.reward_scaler = None
    ckpt.cuda_rng = None
    out = Path(out)
    ckpt.save(out)
    return out


__all__ = ["PRETRAINED", "export_policy", "pretrained", "pretrained_path"]
