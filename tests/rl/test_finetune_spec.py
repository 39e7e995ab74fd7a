"""A run from ``--init-from`` observes by its start's observer spec in its own world (no chain of start files, no
world rewritten to the start's): what the envs of every backend read, what its checkpoint stores, what loads.

The expected specs are written out by hand from the shipped files' (``tests/rl/test_shipped_specs.py``): the
generalist ``berlin`` reads 6 passenger rows per taxi with the time feature over 600 steps, stops and a depth-2
look-ahead; ``berlin_fleet_v1`` reads 6 rows per taxi (24 for its 4 taxis), stops with claims."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import torch

from uamfleet.config import ConfigError
from uamfleet.env.backends import make_vector
from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, StopsSpec, layout_from_dict, layout_to_dict
from uamfleet.presets import make_config
from uamfleet.rl.checkpoint import Checkpoint
from uamfleet.rl.collector import make_run
from uamfleet.rl.distributed import Ranks
from uamfleet.rl.learner import with_init_architecture
from uamfleet.rl.legacy import spec_of, with_stored_spec
from uamfleet.rl.trainer import TrainArgs, load_policy, train

BERLIN = ObserverSpec(
    history_len=3, patch_size=10, passenger_window=None, slots_per_taxi=6.0, time_scale_steps=600,
    stops=StopsSpec(), lookahead=LookaheadSpec(depth=2), hover=False,
)  # fmt: skip
FLEET_V1_WINDOW_24 = ObserverSpec(
    history_len=3, patch_size=10, passenger_window=24, slots_per_taxi=6.0, time_scale_steps=None,
    stops=StopsSpec(claims=True), lookahead=None, hover=False,
)  # fmt: skip


def _p4_args(tmp_path: Path, **overrides: object) -> TrainArgs:
    """One tiny iteration of the generalist on Berlin P4 (4 requests) with 30-step episodes."""
    base: dict[str, object] = dict(
        scenario="berlin_p4", sinr_min_db=-3.0, init_from="berlin", total_timesteps=32, num_envs=1, num_steps=32,
        num_minibatches=2, update_epochs=1, eval_every=1, checkpoint_every=1, time_limit_steps=30, run_dir=tmp_path,
        run_name="p4", progress=False, tensorboard=False, threads=1, learning_rate=1e-12, shaping=0.0,
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)  # type: ignore[arg-type]


def _fleet_args(tmp_path: Path, **overrides: object) -> TrainArgs:
    """One tiny iteration of the first fleet policy (4 taxis, MAPPO critic) on its own scenario, 12-step episodes."""
    base: dict[str, object] = dict(
        scenario="berlin_fleet", sinr_min_db=-5.0, init_from="berlin_fleet_v1", centralised_critic=True,
        total_timesteps=48, num_envs=1, num_steps=12, num_minibatches=2, update_epochs=1, eval_every=1,
        checkpoint_every=1, time_limit_steps=12, fill_tables=False, run_dir=tmp_path, run_name="fleet",
        progress=False, tensorboard=False, threads=1, learning_rate=1e-12, shaping=0.0,
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)  # type: ignore[arg-type]


def test_the_generalist_fine_tuned_on_p4_reads_its_spec_in_the_p4_world(tmp_path: Path) -> None:
    args = _p4_args(tmp_path)
    run = make_run(with_init_architecture(args), None, Ranks(), torch.device("cpu"))
    try:
        assert run.spec == BERLIN
        # the world is the run's own: 4 requests and 30 steps (the start's world had 6 and 600)
        assert (run.cfg.num_passengers, run.cfg.time_limit_steps) == (4, 30)
        assert (run.eval_cfg.num_passengers, run.eval_cfg.time_limit_steps) == (4, 30)
        # ... read as 6 passenger rows (2 padded) by every env of the run
        assert run.layout == BERLIN.layout(run.cfg) and run.layout["passengers"].shape == (6, 12)
        assert run.obs_shapes["stop_paths"] == (6, 3) and run.obs_shapes["heading_lookahead"] == (16,)
        obs, _ = run.venv.reset(seed=0)
        assert obs["passenger_mask"].shape == (1, 1, 6) and not obs["passenger_mask"][..., 4:].any()
    finally:
        run.venv.close()
    train(args)
    for name in ("best.pt", "last.pt"):
        saved = Checkpoint.load(tmp_path / "p4" / name)
        assert saved.spec(name) == BERLIN
        assert saved.world is not None and saved.world["time_limit_steps"] == 30
        assert saved.world["max_passengers"] is None and len(saved.world["requests"]) == 4  # P4's own 4 rows
        assert layout_from_dict(saved.obs_layout or {}) == BERLIN.layout(run.cfg)
    policy, _ = load_policy(tmp_path / "p4" / "best.pt")
    assert policy.spec == BERLIN
    # the same file as format 2 wrote it (no spec stored) is rebuilt through its chain of start files, as it was
    # then: the spec of the start, read in the world laid out as the start's (6 passengers, 600 steps)
    old = dataclasses.replace(saved, observer=None, world=None, format=2)
    assert spec_of(old, "format 2") == BERLIN
    world = with_stored_spec(old, "format 2").world
    assert world is not None and (world["max_passengers"], world["time_limit_steps"]) == (6, 600)
    old.save(tmp_path / "old.pt")  # and a user's format-2 fine-tuned file loads reading its start's spec
    assert load_policy(tmp_path / "old.pt")[0].spec == BERLIN


def test_a_run_window_replaces_the_start_window_and_keeps_the_run_world(tmp_path: Path) -> None:
    args = _fleet_args(tmp_path, passenger_window=24, num_requests=32, reinit_critic=True)
    train(args)
    saved = Checkpoint.load(tmp_path / "fleet" / "last.pt")
    assert saved.spec("last.pt") == FLEET_V1_WINDOW_24
    assert saved.world is not None and saved.world["time_limit_steps"] == 12
    assert saved.world["demand"]["max_requests"] == 32
    world = make_config("berlin_fleet", sinr_min_db=-5.0, time_limit_steps=12, passenger_window=24)
    assert saved.obs_layout == layout_to_dict(FLEET_V1_WINDOW_24.layout(world))
    policy, loaded = load_policy(tmp_path / "fleet" / "last.pt")
    assert policy.spec == FLEET_V1_WINDOW_24 and loaded.net.init_from == "berlin_fleet_v1"


def test_a_centralised_critic_on_a_world_of_another_size_is_refused_in_one_line(tmp_path: Path) -> None:
    # 12 requests: the start's 24 passenger rows are read (12 padded), but the global state holds 12 passengers
    with pytest.raises(ConfigError, match=r"^--init-from='berlin_fleet_v1': its critic reads the global state of 4 "
                       r"taxi\(s\) and 24 passenger\(s\).*12 passenger\(s\).*--reinit-critic") as caught:  # fmt: skip
        train(_fleet_args(tmp_path, num_requests=12))
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("backend", ["inline", "mixture", "workers"])
def test_every_backend_observes_by_the_spec_it_is_given(backend: str) -> None:
    world = make_config("berlin_p4", sinr_min_db=-3.0, time_limit_steps=30)
    cfgs = [world] if backend == "inline" else [world, world.replace(sinr_min_db=-4.0)]
    spec = dataclasses.replace(BERLIN, lookahead=None)
    venv = make_vector(cfgs, 2, backend, workers=1 if backend == "workers" else 0, observer=spec)
    try:
        assert venv.single_observation_space["passengers"].shape == (6, 12)
        obs, _ = venv.reset(seed=0)
        assert obs["stop_paths"].shape == (2, 1, 6, 3) and "heading_lookahead" not in obs
        assert obs["passenger_mask"][..., :4].any() and not obs["passenger_mask"][..., 4:].any()
    finally:
        venv.close()
