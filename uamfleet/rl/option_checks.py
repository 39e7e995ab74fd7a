"""The checks of :class:`~uamfleet.rl.options.TrainArgs` on construction: every numeric option in its range, and
the options that depend on each other (a start for --kl-to-init, a family for --curve-instances, a random-demand
scenario for --map, --thresholds against --sinr-min-db, --fleet-mixture's settings, --vector-backend against
--env-workers), each refused with a :class:`~uamfleet.config.ConfigError` naming the flag and the fix, so a typo
fails before any env is built.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Any

from uamfleet.config import MAX_TAXIS, ConfigError, check_integer, check_number
from uamfleet.instances import FAMILIES, VALIDATION_SEEDS, family_of, fleet_setting, is_map_name, map_family
from uamfleet.radio.packaged import RADIO_MAPS
from uamfleet.rl.option_sets import EnvOptions, EvalOptions, NetOptions, PPOOptions, RunOptions


# Lower bounds of TrainArgs' integer options.
_COUNTS: dict[str, int] = {
    "time_limit_steps": 1, "d_model": 1, "num_heads": 1, "local_window": 1, "seed": 0, "total_timesteps": 1,
    "num_envs": 1, "num_steps": 1, "num_minibatches": 1, "update_epochs": 1, "eval_every": 0,
    "checkpoint_every": 1, "threads": 0, "eval_instances": 0, "env_workers": 0, "curve_instances": 0,
    "curve_every": 1, "warm_start_rounds": 0,
}  # fmt: skip
# (low, high or None, low excluded) of TrainArgs' float options; None values (unset options) are skipped.
_RANGES: dict[str, tuple[float, float | None, bool]] = {
    "sinr_min_db": (-math.inf, None, True), "shaping": (0.0, None, False), "shaping_gamma": (0.0, 1.0, True),
    "shaping_anneal_frac": (0.0, 1.0, False), "learning_rate": (0.0, None, True), "gamma": (0.0, 1.0, True),
    "gae_lambda": (0.0, 1.0, False), "clip_coef": (0.0, None, True), "ent_coef": (0.0, None, False),
    "vf_coef": (0.0, None, False), "max_grad_norm": (0.0, None, True), "target_kl": (0.0, None, True),
    "stop_at_td_m": (0.0, None, False), "max_wall_s": (0.0, None, True), "kl_to_init": (0.0, None, False),
}  # fmt: skip


def flag(name: str) -> str:
    """The command-line flag of an option: ``num_taxis`` -> ``--num-taxis``."""
    return "--" + name.replace("_", "-")


class TrainArgsChecks:
    """The checks :class:`~uamfleet.rl.options.TrainArgs` runs in its ``__post_init__`` (a base class of it)."""

    if TYPE_CHECKING:  # the option groups and accessors of TrainArgs, which the checks read
        env: EnvOptions
        net: NetOptions
        ppo: PPOOptions
        eval: EvalOptions
        run: RunOptions

        def _get(self, name: str) -> Any: ...
        def _set(self, name: str, value: Any) -> None: ...

    def _check_start(self) -> None:
        """What a run starts from: --kl-to-init, --reinit-critic and --warm-start-rounds need (or refuse) a start."""
        net = self.net
        if net.kl_to_init > 0 and net.init_from is None and not net.warm_start_rounds:
            raise ConfigError(
                f"--kl-to-init={net.kl_to_init:g} pulls the policy toward the one it starts from; give that policy "
                "with --init-from (a shipped name such as berlin, or a checkpoint file) or build it with "
                "--warm-start-rounds, or drop --kl-to-init."
            )
        if net.warm_start_rounds and net.init_from is not None:
            raise ConfigError(f"--warm-start-rounds={net.warm_start_rounds} warm-starts a network from scratch; drop "
                              f"it or --init-from={net.init_from!r}.")  # fmt: skip
        if net.reinit_critic and net.init_from is None:
            raise ConfigError(
                "--reinit-critic starts the critic of an --init-from policy afresh; give that policy with "
                "--init-from, or drop --reinit-critic (a run from scratch starts every weight afresh)."
            )

    def _check_numbers(self) -> None:
        """The integer options against their lower bounds, the float options against their intervals."""
        for name, minimum in _COUNTS.items():
            check_integer(flag(name), self._get(name), minimum)
        most = 4 * (os.cpu_count() or 1)
        check_integer("--threads", self.run.threads, 0, most, fix=" (4 per CPU core at most; 0: torch's default)")
        for name in ("num_taxis", "eval_time_limit_steps", "passenger_window"):
            if self._get(name) is not None:
                check_integer(flag(name), self._get(name), 1)
        for name, (low, high, low_open) in _RANGES.items():
            value = self._get(name)
            if value is None:
                continue
            check_number(flag(name), value)
            if (value <= low if low_open else value < low) or (high is not None and value > high):
                interval = f"{'(' if low_open else '['}{low:g}, {'inf)' if high is None else f'{high:g}]'}"
                raise ConfigError(f"{flag(name)}={value!r} is out of range: it must lie in {interval}.")

    def _check_curve(self) -> None:
        """--curve-instances within the validation split, and a family to draw them from; --schedule-clock known,
        and with first_delivery, evaluations during the run to start it."""
        if self.ppo.schedule_clock not in ("steps", "first_delivery"):
            raise ConfigError(f"--schedule-clock={self.ppo.schedule_clock!r} is unknown; use steps or first_delivery.")
        if self.ppo.schedule_clock == "first_delivery" and self.eval.eval_every == 0:
            raise ConfigError(
                "--schedule-clock first_delivery starts the schedules at the first greedy evaluation that delivers "
                "everyone, but --eval-every 0 evaluates only at the end; give --eval-every >= 1."
            )
        count, family = self.eval.curve_instances, self.eval.curve_family
        if count > len(VALIDATION_SEEDS):
            raise ConfigError(
                f"--curve-instances={count} exceeds the {len(VALIDATION_SEEDS):,} seeds of the validation split; "
                "give at most that (e.g. 10)."
            )
        if family is not None and family not in FAMILIES:
            raise ConfigError(f"--curve-family={family!r} is unknown; use one of {sorted(FAMILIES)}.")
        if count and family is None and isinstance(self.env.scenario, str):
            try:
                family_of(self.env.scenario)
            except ValueError:
                raise ConfigError(
                    f"--curve-instances={count} flies validation instances, but scenario {self.env.scenario!r} "
                    f"belongs to no instance family; name one with --curve-family (e.g. berlin)."
                ) from None

    def _check_map(self) -> None:
        """--map names a map (a packaged one or a file), on a scenario of random demand, without --eval-instances
        (the trainer draws those from the scenario's own family)."""
        env = self.env
        if env.map is None:
            return
        if not (env.map in RADIO_MAPS or is_map_name(env.map)):
            raise ConfigError(
                f"--map={env.map!r}: no packaged map of that name and no such map file; give one of "
                f"{', '.join(RADIO_MAPS)} or the path of a map file (.npz of uamfleet-radio-map)."
            )
        if env.scenario in ("berlin_p4", "detroit_p5", "detroit3gpp_p5"):
            raise ConfigError(
                f"--map={env.map!r} with --scenario {env.scenario}: a fixed scenario's stops lie on its own map; "
                "give a scenario of random demand, e.g. --scenario berlin_instances."
            )
        if self.eval.eval_instances:
            raise ConfigError(
                f"--eval-instances={self.eval.eval_instances} with --map: the trainer draws them from the scenario's "
                "own family and map; fly the map's validation instances with --curve-instances N, --eval-instances 0."
            )
        map_family(env.map)  # a file that is no map, or too small a map, is refused now

    def _check_thresholds(self) -> None:
        """--thresholds: a list of distinct dB values, not given together with --sinr-min-db (stored as a tuple)."""
        given = self.env.thresholds
        if isinstance(given, str | bytes) or not hasattr(given, "__iter__"):
            raise ConfigError(f"--thresholds={given!r} must be a list of dB values, e.g. -7 -6 -5.")
        thresholds = tuple(check_number("--thresholds", t) for t in given)
        self._set("thresholds", thresholds)
        repeated = sorted({t for t in thresholds if thresholds.count(t) > 1})
        if repeated:
            raise ConfigError(
                f"--thresholds={list(thresholds)} repeats {repeated}: each threshold is one share of the envs; "
                "give each once."
            )
        if thresholds and self.env.sinr_min_db is not None:
            raise ConfigError(
                f"--sinr-min-db={self.env.sinr_min_db} and --thresholds={list(thresholds)} both set the threshold; "
                "give one of them."
            )

    def _check_fleet_mixture(self) -> None:
        """--num-requests and --fleet-mixture: a *_fleet scenario, settings <taxis>x<requests>, each given once,
        --num-taxis the largest fleet (stored as a tuple of strings)."""
        env = self.env
        fleet = env.scenario.endswith("_fleet") if isinstance(env.scenario, str) else False
        if env.num_requests is not None:
            check_integer("--num-requests", env.num_requests, 1)
            if not fleet:
                raise ConfigError(
                    f"--num-requests={env.num_requests} sets a fleet scenario's demand; it needs a *_fleet scenario "
                    f"(not {env.scenario!r}), e.g. --scenario berlin_fleet."
                )
        if isinstance(env.fleet_mixture, str | bytes) or not hasattr(env.fleet_mixture, "__iter__"):
            raise ConfigError(f"--fleet-mixture={env.fleet_mixture!r} must be a list of settings, e.g. 2x12 4x48.")
        mixture = tuple(str(s) for s in env.fleet_mixture)
        self._set("fleet_mixture", mixture)
        if not mixture:
            return
        if not fleet:
            raise ConfigError(
                f"--fleet-mixture={list(mixture)} mixes fleet settings; it needs a *_fleet scenario "
                f"(not {env.scenario!r}), e.g. --scenario berlin_fleet."
            )
        settings = self.fleet_settings()
        repeated = sorted({s for s in mixture if mixture.count(s) > 1})
        if repeated:
            raise ConfigError(f"--fleet-mixture={list(mixture)} repeats {repeated}; give each setting once.")
        largest = max(taxis for taxis, _ in settings)
        if env.num_taxis is not None and env.num_taxis != largest:
            raise ConfigError(
                f"--num-taxis={env.num_taxis} is not the largest fleet of --fleet-mixture={list(mixture)} "
                f"({largest}): the run's observation holds the largest fleet's other taxis; set --num-taxis {largest} "
                "or leave it out."
            )

    def _check_vector_backend(self) -> None:
        """--vector-backend: a known name that agrees with --env-workers, --thresholds and --fleet-mixture."""
        env = self.env
        backend, workers = env.vector_backend, env.env_workers
        if backend not in ("auto", "inline", "mixture", "workers"):
            raise ConfigError(f"--vector-backend={backend!r} is unknown; use auto, inline, mixture or workers.")
        if backend == "workers" and not workers:
            raise ConfigError(
                "--vector-backend workers steps the envs in worker processes; give --env-workers >= 1 (or use auto)."
            )
        if backend in ("inline", "mixture") and workers:
            raise ConfigError(
                f"--vector-backend {backend} steps the envs in this process, but --env-workers={workers} asks for "
                "worker processes; use --vector-backend workers (or auto), or drop --env-workers."
            )
        configs = max(1, len(env.thresholds)) * max(1, len(env.fleet_mixture))
        if backend == "inline" and configs > 1:
            raise ConfigError(
                f"--vector-backend inline steps one config, but --thresholds and --fleet-mixture give {configs}; use "
                "--vector-backend mixture (or auto)."
            )

    def fleet_settings(self) -> list[tuple[int, int]]:
        """(taxis, requests) of each --fleet-mixture setting, in the order given (ConfigError for a malformed one)."""
        out = []
        for setting in self.env.fleet_mixture:
            taxis, requests = fleet_setting(setting, "--fleet-mixture")
            out.append((check_integer("--fleet-mixture taxis", taxis, 1, MAX_TAXIS), requests))
        return out


__all__ = ["TrainArgsChecks", "flag"]
