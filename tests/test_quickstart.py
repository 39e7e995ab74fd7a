"""The main job's training recipes (uamfleet/cli/quickstart.py): what each hands the trainer, and why (issues 20 and
41). Their runs over 10 seeds are docs/results/quickstart_seeds.csv (docs/getting-started.md, "The main job")."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from uamfleet.cli import quickstart
from uamfleet.metrics import EpisodeMetrics
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


def test_the_main_job_trains_from_random_weights_with_the_search_warm_start(tmp_path, capsys):
    """The default recipe (issue 41: the main job's training from scratch) is scratch-search-start: no start policy,
    2 rounds of DAgger from replan's search, then 100k agent-steps of PPO (whole iterations: 48 of 32 envs x 64
    steps, 98,304 agent-steps) with a KL term toward the warm start, evaluating after every iteration."""
    recipe = trainer_options(tmp_path, [])
    assert quickstart.DEFAULT_RECIPE == "scratch-search-start"
    assert recipe == trainer_options(tmp_path, ["--recipe", "scratch-search-start"])
    assert recipe.net.init_from is None and recipe.net.warm_start_rounds == 2 and recipe.net.kl_to_init == 0.01
    assert recipe.eval.eval_every == 1 and recipe.run.threads == 1 and recipe.ppo.seed == 1
    assert recipe.env.scenario == "berlin_p4" and recipe.env.sinr_min_db == -3.0 and recipe.net.variant == "de_msfea"
    assert recipe.ppo.total_timesteps == 100_000
    assert (recipe.eval.curve_instances, recipe.eval.curve_family) == (10, "berlin")  # the curve's validation panel
    out = capsys.readouterr().out
    assert "training MSHA-PPO (de_msfea) from scratch on Berlin P4 at -3 dB for 100,000 agent-steps" in out
    assert "recipe scratch-search-start" in out


def test_fine_tuning_starts_from_the_shipped_generalist_on_its_own_reward(tmp_path, capsys):
    """--recipe fine-tune starts from uamfleet.pretrained("berlin") with a KL term toward it, evaluates after every
    iteration (and the start first: tests/rl/test_fine_tuning.py), and trains on the reward the start was trained
    on (read here from the shipped checkpoint itself), so the value head and the advantages mean what they meant.
    Naming a start with --init-from selects it too."""
    recipe = trainer_options(tmp_path, ["--recipe", "fine-tune"])
    assert recipe == trainer_options(tmp_path, ["--init-from", "berlin"])
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
    recipe = trainer_options(tmp_path, ["--recipe", "scratch"])
    for phi in (-20.0, -5.0, -1.0):
        assert shaping_of(recipe, phi, phi) == 0.0
        assert shaping_of(recipe, phi, phi + 1) == pytest.approx(50.0)
    old = trainer_options(tmp_path, ["--recipe", "scratch", "--shaping-gamma", "0.9"])
    assert shaping_of(old, -20.0, -20.0) == pytest.approx(100.0)
    assert "training MSHA-PPO (de_msfea) from scratch" in capsys.readouterr().out


def test_the_recipe_from_scratch_evaluates_every_iteration_and_keeps_the_rest_of_the_trainer_defaults(tmp_path):
    recipe = trainer_options(tmp_path, ["--recipe", "scratch"])
    assert recipe.net.init_from is None and recipe.net.kl_to_init == 0.0
    assert recipe.eval.eval_every == 1  # best.pt: the shortest greedy tour of any iteration, not of every 5th
    assert recipe.run.threads == 1 and recipe.ppo.seed == 1 and recipe.ppo.total_timesteps == 150_000
    assert recipe.env.scenario == "berlin_p4" and recipe.env.sinr_min_db == -3.0 and recipe.net.variant == "de_msfea"
    defaults = TrainArgs()
    for name in ("gamma", "learning_rate", "ent_coef", "shaping", "shaping_anneal_frac", "num_envs", "num_steps"):
        assert recipe.flat()[name] == defaults.flat()[name], name
    assert recipe.eval.max_wall_s == 600.0  # --minutes 10


def test_the_old_recipe_is_one_flag_pair_away(tmp_path):
    """--recipe scratch --shaping-gamma 0.9 --eval-every 5 is the recipe of the README before issue 20 (its 10
    seeds are in docs/results/quickstart_seeds.csv), and --recipe scratch alone the from-scratch recipe after it, so
    both measurements can be repeated."""
    old = trainer_options(
        tmp_path, ["--recipe", "scratch", "--shaping-gamma", "0.9", "--eval-every", "5", "--seed", "3"]
    )
    assert (old.env.shaping_gamma, old.eval.eval_every, old.ppo.seed) == (0.9, 5, 3)


SCRATCH_RECIPES = ("scratch", "scratch-first-delivery", "scratch-workers", "scratch-search-start")


def test_each_recipe_builds_its_trainer_options(tmp_path):
    """--recipe names the training: scratch-search-start is the default's, fine-tune what --init-from selects, and
    the recipes from scratch differ from scratch only in the options they name (plan of issue 41, section 3.2)."""
    assert trainer_options(tmp_path, ["--recipe", "scratch-search-start"]) == trainer_options(tmp_path, [])
    scratch = trainer_options(tmp_path, ["--recipe", "scratch"])
    assert scratch.net.init_from is None and scratch.ppo.schedule_clock == "steps"
    delivery = trainer_options(tmp_path, ["--recipe", "scratch-first-delivery"])
    assert delivery == scratch.with_options(schedule_clock="first_delivery")
    workers = trainer_options(tmp_path, ["--recipe", "scratch-workers"])
    assert workers == scratch.with_options(schedule_clock="first_delivery", num_envs=64, env_workers=2)
    assert workers.chosen_backend() == "workers"
    search = trainer_options(tmp_path, ["--recipe", "scratch-search-start"])  # R2: the search warm start
    assert search == delivery.with_options(
        warm_start_rounds=2, kl_to_init=0.01, learning_rate=3e-4, total_timesteps=100_000
    )
    assert trainer_options(tmp_path, ["--recipe", "scratch-search-start", "--total-timesteps", "4096"]) == (
        search.with_options(total_timesteps=4096)
    )
    assert set(quickstart.RECIPES) == {"fine-tune", *SCRATCH_RECIPES}
    curve = trainer_options(tmp_path, ["--recipe", "scratch", "--curve-instances", "5"])
    assert (curve.eval.curve_instances, curve.eval.curve_family) == (5, "berlin")
    assert curve == scratch.with_options(curve_instances=5, curve_family="berlin")


def test_a_recipe_the_quickstart_does_not_know_is_a_one_line_error(tmp_path, capsys):
    assert quickstart.cli(["--recipe", "scratch-fast", "--run-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("uamfleet-quickstart: error: --recipe='scratch-fast' is unknown; use one of fine-tune, ")
    assert err.count("\n") == 1
    for recipe in SCRATCH_RECIPES:  # a start named for a recipe from random weights is a contradiction, not ignored
        assert quickstart.cli(["--recipe", recipe, "--init-from", "berlin", "--run-dir", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert f"--recipe {recipe} trains from random weights, but --init-from='berlin' names a start" in err
        assert "use --recipe fine-tune to train from it" in err and err.count("\n") == 1


@pytest.mark.slow
def test_a_tiny_run_logs_the_validation_curve_and_draws_it(tmp_path, monkeypatch, capsys):
    """One iteration from scratch with --curve-instances 2 (the flights of the table stubbed: not what is tested):
    its evaluation row in progress.csv has val_td_m and val_pr_pct, and curve.png is written beside tb/."""
    metrics = EpisodeMetrics(
        5000.0, 100.0, 59.0, 28.0, 100.0, 91.6, -2.0, 200.0, 4, 4, 50.0, 60.0, 1.2, 1.0, 0, 0.1, 50
    )
    monkeypatch.setattr(quickstart, "fly", lambda *a, **k: metrics)
    argv = ["--recipe", "scratch-first-delivery", "--total-timesteps", str(32 * 64), "--curve-instances", "2",
            "--no-generalist", "--run-dir", str(tmp_path)]  # fmt: skip
    assert quickstart.cli(argv) == 0
    folder = tmp_path / quickstart.DEFAULT_RUN
    with (folder / "progress.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and float(rows[0]["val_td_m"]) > 0 and 0 <= float(rows[0]["val_pr_pct"]) <= 100
    png = (folder / "curve.png").read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 1000 and (folder / "tb").is_dir()
    assert "recipe scratch-first-delivery" in capsys.readouterr().out
