"""The main job's training recipe (uamfleet/cli/quickstart.py): what it hands the trainer, and why (issue 20, part 4).

The 10-seed measurement behind the recipe is in docs/results.md, "The main job over 10 seeds (issue 20)"."""

from __future__ import annotations

from pathlib import Path

import pytest

from uamfleet.cli import quickstart
from uamfleet.rl.checkpoint import Checkpoint, pretrained_path
from uamfleet.rl.legacy import checkpoint_args
from uamfleet.rl.options import TrainArgs, make_env_config


class Captured(Exception):
    """Raised by the stand-in trainer once it has the options, so no training runs."""

    def __init__(self, args: TrainArgs) -> None:
        super().__init__("captured")
        self.options = args


def trainer_options(tmp_path: Path, argv: list[str]) -> TrainArgs:
    """The TrainArgs the command line ``uamfleet-quickstart argv`` hands to the trainer (which does not run)."""

    def stand_in(args: TrainArgs) -> None:
        raise Captured(args)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(quickstart, "train", stand_in)
        with pytest.raises(Captured) as caught:
            quickstart.cli([*argv, "--run-dir", str(tmp_path)])
    return caught.value.options


def shaping_of(args: TrainArgs, potential: float, next_potential: float) -> float:
    """The shaping term the env pays for one step, F = w (gamma_Phi Phi(s') - Phi(s)), from the config the run
    trains on (uamfleet.rl.options.make_env_config), written out by hand."""
    reward = make_env_config(args.env.scenario, args).reward
    return reward.shaping * (reward.shaping_gamma * next_potential - potential)


def test_the_main_job_fine_tunes_the_shipped_generalist_on_its_own_reward(tmp_path, capsys):
    """The default recipe starts from uamfleet.pretrained("berlin") with a KL term toward it, evaluates after every
    iteration (and the start first: tests/rl/test_fine_tuning.py), and trains on the reward the start was trained
    on (read here from the shipped checkpoint itself), so the value head and the advantages mean what they meant."""
    recipe = trainer_options(tmp_path, [])
    assert recipe.net.init_from == "berlin" and recipe.net.kl_to_init == 0.01 and recipe.eval.eval_every == 1
    assert recipe.env.scenario == "berlin_p4" and recipe.env.sinr_min_db == -3.0 and recipe.run.threads == 1
    assert recipe.ppo.total_timesteps == quickstart.FINE_TUNE_STEPS == 24 * 32 * 64  # whole iterations
    start = checkpoint_args(Checkpoint.load(pretrained_path("berlin")))
    assert (recipe.env.shaping, recipe.ppo.gamma) == (start.env.shaping, start.ppo.gamma) == (0.0, 0.995)
    assert "fine-tuning 'berlin' with PPO on Berlin P4 at -3 dB for 49,152 agent-steps" in capsys.readouterr().out


def test_the_recipe_from_scratch_pays_nothing_for_staying_away_from_the_stops(tmp_path, capsys):
    """With the trainer's gamma (0.9) inside the shaping term, a taxi that stays 20 steps from its next stop
    (Phi = -20) earns w (1 - 0.9) 20 = 100 per step: the hover trap that stalled seeds 3 and 6 of the earlier recipe
    (docs/results.md). The quickstart's recipe shapes with gamma_Phi = 1: standing still pays 0, progress pays w
    per step of progress, at any distance."""
    recipe = trainer_options(tmp_path, ["--init-from", "None"])
    for phi in (-20.0, -5.0, -1.0):
        assert shaping_of(recipe, phi, phi) == 0.0
        assert shaping_of(recipe, phi, phi + 1) == pytest.approx(50.0)
    old = trainer_options(tmp_path, ["--init-from", "None", "--shaping-gamma", "0.9"])
    assert shaping_of(old, -20.0, -20.0) == pytest.approx(100.0)
    assert "training MSHA-PPO (de_msfea) from scratch" in capsys.readouterr().out


def test_the_recipe_from_scratch_evaluates_every_iteration_and_keeps_the_rest_of_the_trainer_defaults(tmp_path):
    recipe = trainer_options(tmp_path, ["--init-from", "None"])
    assert recipe.net.init_from is None and recipe.net.kl_to_init == 0.0
    assert recipe.eval.eval_every == 1  # best.pt: the shortest greedy tour of any iteration, not of every 5th
    assert recipe.run.threads == 1 and recipe.ppo.seed == 1 and recipe.ppo.total_timesteps == 150_000
    assert recipe.env.scenario == "berlin_p4" and recipe.env.sinr_min_db == -3.0 and recipe.net.variant == "de_msfea"
    defaults = TrainArgs()
    for name in ("gamma", "learning_rate", "ent_coef", "shaping", "shaping_anneal_frac", "num_envs", "num_steps"):
        assert recipe.flat()[name] == defaults.flat()[name], name
    assert recipe.eval.max_wall_s == 600.0  # --minutes 10


def test_the_old_recipe_is_one_flag_pair_away(tmp_path):
    """--init-from None --shaping-gamma 0.9 --eval-every 5 is the recipe of the README before issue 20 (its 10
    seeds are in docs/results.md), and --init-from None alone the from-scratch recipe after it, so both measurements
    can be repeated."""
    old = trainer_options(
        tmp_path, ["--init-from", "None", "--shaping-gamma", "0.9", "--eval-every", "5", "--seed", "3"]
    )
    assert (old.env.shaping_gamma, old.eval.eval_every, old.ppo.seed) == (0.9, 5, 3)
