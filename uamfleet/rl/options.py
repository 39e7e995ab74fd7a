"""The training options: :class:`TrainArgs` (every flag of ``train/ppo.py``, checked on construction by
:mod:`uamfleet.rl.option_checks`), in groups (env, observer, net, ppo, eval, run: the frozen dataclasses of
:mod:`uamfleet.rl.option_sets`, flags flat, ``--help`` in those sections), and the env config a run trains and
evaluates on (:func:`make_env_config`). A checkpoint's options are read back by
:func:`uamfleet.rl.legacy.checkpoint_args`, without importing the training loop.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

from uamfleet.config import ConfigError, EnvConfig
from uamfleet.instances import VALIDATION_SEEDS, family_of, map_family, map_family_name
from uamfleet.presets import make_config
from uamfleet.rl.option_checks import TrainArgsChecks, flag
from uamfleet.rl.option_groups import Flat, flat_options, grouped_from_flat
from uamfleet.rl.option_sets import (
    GROUP_OF,
    GROUPS,
    EnvOptions,
    EvalOptions,
    NetOptions,
    ObserverOptions,
    PPOOptions,
    RunOptions,
)


@dataclass(frozen=True)
class TrainArgs(TrainArgsChecks):
    """PPO training of the shared MSHA policy (every option is a command-line flag of ``train/ppo.py``), in groups.

    A checkpoint stores the options flat (:meth:`flat`, one key per option, plain values), and
    :meth:`from_flat` reads such a dict back; ``args.ppo.learning_rate`` is ``args.flat()["learning_rate"]``."""

    env: Annotated[EnvOptions, Flat] = field(default_factory=EnvOptions)
    observer: Annotated[ObserverOptions, Flat] = field(default_factory=ObserverOptions)
    net: Annotated[NetOptions, Flat] = field(default_factory=NetOptions)
    ppo: Annotated[PPOOptions, Flat] = field(default_factory=PPOOptions)
    eval: Annotated[EvalOptions, Flat] = field(default_factory=EvalOptions)
    run: Annotated[RunOptions, Flat] = field(default_factory=RunOptions)

    @classmethod
    def from_flat(cls, flat: Mapping[str, Any]) -> TrainArgs:
        """The options of a flat dict (as :meth:`flat` gives and a checkpoint stores; options it lacks take their
        defaults); ConfigError naming any key that is no option."""
        return grouped_from_flat(cls, flat)

    @classmethod
    def from_saved(cls, saved: Mapping[str, Any]) -> TrainArgs:
        """The options of a checkpoint's flat ``args``: keys that are no option (an imitation run's ``imitation``)
        are left out, options added since the checkpoint was written take their defaults."""
        return cls.from_flat({name: value for name, value in saved.items() if name in GROUP_OF})

    def flat(self) -> dict[str, Any]:
        """Every option by name, as plain values (paths as strings): what a checkpoint stores as its ``args``."""
        return {name: (str(v) if isinstance(v, Path) else v) for name, v in self._values().items()}

    def with_options(self, **options: Any) -> TrainArgs:
        """These options with ``options`` (flat names, e.g. ``num_taxis=4``) replaced; checked like any."""
        return TrainArgs.from_flat({**self._values(), **options})

    def _values(self) -> dict[str, Any]:
        return flat_options(self)

    def _get(self, name: str) -> Any:
        return getattr(getattr(self, GROUP_OF[name]), name)

    def _set(self, name: str, value: Any) -> None:
        """Store an option's normalised value (a tuple for a list) in its frozen group."""
        object.__setattr__(getattr(self, GROUP_OF[name]), name, value)

    def __post_init__(self) -> None:
        """Every numeric option in its range (:class:`~uamfleet.config.ConfigError` naming the flag otherwise),
        so a typo fails before any env is built, not after training (``checkpoint_every=0``)."""
        for group, cls in GROUPS.items():
            if not isinstance(getattr(self, group), cls):
                raise ConfigError(f"TrainArgs.{group}={getattr(self, group)!r} must be a {cls.__name__}.")
        self._check_numbers()
        self._check_thresholds()
        env, evaluation = self.env, self.eval
        if evaluation.eval_instances > len(VALIDATION_SEEDS):
            raise ConfigError(
                f"--eval-instances={evaluation.eval_instances} exceeds the {len(VALIDATION_SEEDS):,} seeds of the "
                f"validation split; give at most {len(VALIDATION_SEEDS):,} (e.g. 50)."
            )
        if evaluation.eval_instances and not env.scenario.endswith(("_instances", "_fleet")):
            raise ConfigError(
                f"--eval-instances={evaluation.eval_instances} flies held-out instances of a family; it needs a "
                f"*_instances or *_fleet scenario (not {env.scenario!r}), e.g. --scenario berlin_instances."
            )
        self._check_map()
        self._check_curve()
        self._check_fleet_mixture()
        self._check_vector_backend()
        self._check_start()
        for name in ("scenario", "run_name", "init_from"):
            value = self._get(name)
            if value is not None and not isinstance(value, str):
                raise ConfigError(f"{flag(name)}={value!r} must be a string.")
        self._set("run_dir", Path(self.run.run_dir))

    def curve_family_name(self) -> str:
        """The family of the --curve-instances flights: --curve-family, else --map's, else the scenario's own."""
        return self.eval.curve_family or self.env.map or family_of(self.env.scenario)

    def chosen_backend(self) -> str:
        """The backend that steps the training envs: --vector-backend, with auto resolved (workers with
        --env-workers, else mixture with --thresholds or --fleet-mixture, else inline)."""
        env = self.env
        if env.vector_backend != "auto":
            return env.vector_backend
        if env.env_workers:
            return "workers"
        return "mixture" if env.thresholds or env.fleet_mixture else "inline"

    @property
    def name(self) -> str:
        if self.run.run_name:
            return self.run.run_name
        sinr = "default" if self.env.sinr_min_db is None else f"{self.env.sinr_min_db:g}"
        place = "" if self.env.map is None else f"{map_family_name(self.env.map)}_"
        return f"{place}{self.env.scenario}_{sinr}dB_{self.net.variant}_s{self.ppo.seed}"

    def env_overrides(self, training: bool = True) -> dict[str, Any]:
        env, observer = self.env, self.observer
        overrides: dict[str, Any] = {"feasibility": env.feasibility}
        if env.map is not None:  # the map, at its family's strictest threshold unless one is given
            overrides["radio"] = env.map
            overrides["sinr_min_db"] = map_family(env.map).thresholds_db[-1]
        if env.sinr_min_db is not None:
            overrides["sinr_min_db"] = env.sinr_min_db
        taxis = env.num_taxis
        if taxis is None and env.fleet_mixture:
            taxis = max(n for n, _ in self.fleet_settings())
        if taxis is not None:
            overrides["num_taxis"] = taxis
        evaluation_limit = self.eval.eval_time_limit_steps
        overrides["time_limit_steps"] = (
            env.time_limit_steps if training or evaluation_limit is None else evaluation_limit
        )
        if observer.heading_lookahead:
            overrides["heading_lookahead"] = True
        if observer.lookahead_depth != 1:
            overrides["lookahead_depth"] = observer.lookahead_depth
        if observer.passenger_window is not None:
            overrides["passenger_window"] = observer.passenger_window
        return overrides


def make_env_config(scenario: str | EnvConfig, args: TrainArgs, training: bool = True) -> EnvConfig:
    """The env config a run trains (or evaluates) on: the scenario with the run's overrides and shaping.

    The shaping term uses the trainer's discount unless ``args.env.shaping_gamma`` is set, so by default it stays
    potential-based for the return PPO maximises (Ng et al. 1999: F = gamma * Phi(s') - Phi(s) with the MDP's own
    gamma)."""
    cfg = make_config(scenario, **args.env_overrides(training=training))
    env = args.env
    if env.num_requests is not None:
        cfg = with_num_requests(cfg, env.num_requests)
    reward = dataclasses.replace(
        cfg.reward,
        shaping=env.shaping,
        shaping_metric=env.shaping_metric,
        shaping_gamma=args.ppo.gamma if env.shaping_gamma is None else env.shaping_gamma,
    )
    return cfg.replace(reward=reward)


def with_num_requests(cfg: EnvConfig, requests: int) -> EnvConfig:
    """A random-demand config with exactly ``requests`` per episode (its arrival law and window kept) and a
    passenger axis that holds them (a passenger window, when set, still decides the rows observed)."""
    demand = dataclasses.replace(
        cfg.demand, min_requests=requests, max_requests=requests, num_initial=min(cfg.demand.num_initial, requests)
    )
    return cfg.replace(demand=demand, max_passengers=requests)
