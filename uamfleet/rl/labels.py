"""Labels of the hedge for expert iteration: the network flies, the search says what it should have done.

:func:`label_instance` flies the network's own greedy decoding through one instance (DAgger: the states the network
visits; with ``beta`` > 0 a share of the expert's actions is flown instead) and labels its states:

- while a request may still come (the demand model draws a future), every ``every``-th step with the hedge's scores
  (:meth:`~uamfleet.rl.guided.AnticipatingGuidedSearch.scores_at`) over ``futures`` futures drawn from a generator
  seeded by the instance and the step (:func:`label_futures`, so a label can be replayed): a soft target
  q(c) ∝ exp(-(mean_moves(c) - min) / T) over the candidates' first actions, weighted 1 - exp(-gap / T) by the gap
  between the best and the second best;
- once nothing can come, every step with ``replan``'s step-level solver over the then complete requests
  (:class:`~uamfleet.rl.experts.ReplanExpert`: one plan held until the flown action leaves it, the network's action
  kept where it is as short), as a one-hot target of weight 1.

:func:`label_instances` labels many instances in a pool of spawned processes (one torch thread each), one ``.npz``
per instance, and reports what the labels cost (:class:`LabelCost`).
"""

from __future__ import annotations

import io
import multiprocessing
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch

from uamfleet.baselines.anticipation import DemandPrior
from uamfleet.baselines.demand_models import DemandModel
from uamfleet.checks import MAX_SEED, check_integer, check_number
from uamfleet.config import EnvConfig
from uamfleet.env.protocol import observer_of
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import check_family, make_instance
from uamfleet.io import write_bytes_atomic
from uamfleet.rl.experts import NO_LABEL, ReplanExpert, released_count
from uamfleet.rl.guided import (
    MAX_EXPERT_BEAM,
    MAX_FUTURES,
    MAX_STEPS,
    WAIT_ACTIONS,
    AnticipatingGuidedSearch,
    SearchScores,
)
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS, FleetState

NUM_ACTIONS = HOVER_ACTION + 1
"""The width of a target: the 16 headings and the hover action."""
HEDGE, FINISH = 0, 1
"""``Labels.source``: a hedge label (a request may still come), a finish label (every request is known)."""
FUTURES_STREAM = 4101
"""The first word of every label's futures generator (:func:`label_futures`), apart from the other streams."""


@dataclass(frozen=True)
class LabelOptions:
    """How :func:`label_instance` labels: a hedge label every ``every``-th step while a request may still come, over
    ``futures`` futures (more than at run time: labelling is not real-time), soft at ``temperature`` (moves);
    after, ``replan``'s solver of beam ``finish_beam`` labels every step; ``beta`` the share of the expert's actions
    flown (0: the network's own states). ``wait_action``, ``first_headings``, ``commit`` and ``tail`` are the
    hedge's (:class:`~uamfleet.rl.guided.AnticipatingGuidedSearch`); ``tail`` None flies every rollout to its end."""

    every: int = 2
    futures: int = 16
    temperature: float = 0.5
    finish_beam: int = 32
    wait_action: str = "hover"
    beta: float = 0.0
    first_headings: int = 4
    commit: int = 4
    tail: int | None = 10

    def __post_init__(self) -> None:
        check_integer("every", self.every, 1, MAX_STEPS, fix=" (label every k-th step, e.g. 2)")
        check_integer("futures", self.futures, 1, MAX_FUTURES, fix=" (futures per label, e.g. 16)")
        check_number("temperature", self.temperature, positive=True)
        check_integer("finish_beam", self.finish_beam, 1, MAX_EXPERT_BEAM, fix=" (replan's beam, e.g. 32)")
        if self.wait_action not in WAIT_ACTIONS:
            raise ValueError(f"wait_action={self.wait_action!r} is unknown; choose one of {WAIT_ACTIONS}.")
        beta = check_number("beta", self.beta)
        if not 0.0 <= beta <= 1.0:
            raise ValueError(f"beta={self.beta!r} is outside [0, 1]; give the share of the expert's actions, e.g. 0.")
        check_integer("first_headings", self.first_headings, 1, NUM_HEADINGS, fix=" (e.g. 4)")
        check_integer("commit", self.commit, 1, MAX_STEPS, fix=" (steps a wait holds, e.g. 4)")
        if self.tail is not None:
            check_integer("tail", self.tail, 0, MAX_STEPS, fix=" or None (every rollout to its end), e.g. 10")


class Labels(NamedTuple):
    """N labelled states. ``obs`` holds the observation fields as the policy's observer reads them, [N, A, ...]
    (A = 1 taxi), so a fit feeds them to the network as they are."""

    obs: dict[str, np.ndarray]
    target: np.ndarray  # [N, 17] float32: soft over the hedge's candidates, one-hot for a finish label
    action: np.ndarray  # [N] int64: the best candidate's first action / the plan's first heading (16 = hover)
    weight: np.ndarray  # [N] float32: 1 - exp(-gap / T) (hedge), 1 (finish)
    source: np.ndarray  # [N] int8: HEDGE or FINISH
    promised_moves: np.ndarray  # [N] float64: the best candidate's mean moves / the plan's moves
    plan: np.ndarray  # [N, L] int16, -1 padded: the best candidate's held action(s) / the finish plan from the step
    seed: np.ndarray  # [N] int64: the instance's seed
    step: np.ndarray  # [N] int64: the step labelled

    @property
    def num_labels(self) -> int:
        """N, the states labelled."""
        return len(self.action)

    def save(self, path: str | Path) -> Path:
        """Write the labels to the ``.npz`` file ``path`` atomically."""
        arrays = {f"obs/{k}": v for k, v in self.obs.items()}
        arrays.update({k: getattr(self, k) for k in self._fields if k != "obs"})
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)  # type: ignore[arg-type]
        return write_bytes_atomic(path, buffer.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> Labels:
        """The labels :meth:`save` wrote to ``path``."""
        if not Path(path).is_file():
            raise FileNotFoundError(
                f"no labels file {str(path)!r}; give a .npz that Labels.save or label_instances wrote."
            )
        with np.load(path, allow_pickle=False) as data:
            obs = {k[4:]: data[k] for k in data.files if k.startswith("obs/")}
            return cls(obs=obs, **{k: data[k] for k in cls._fields[1:]})

    @classmethod
    def concat(cls, parts: Sequence[Labels]) -> Labels:
        """The labels of ``parts`` one after another (plans padded to the longest)."""
        if not parts:
            raise ValueError("Labels.concat needs at least one Labels; give the labels of one instance or more.")
        parts = [p for p in parts if p.num_labels] or list(parts[:1])
        width = max(p.plan.shape[1] for p in parts)
        joined: dict[str, Any] = {
            k: np.concatenate([getattr(p, k) for p in parts]) for k in cls._fields if k not in ("obs", "plan")
        }
        joined["plan"] = np.concatenate(
            [np.pad(p.plan, ((0, 0), (0, width - p.plan.shape[1])), constant_values=-1) for p in parts]
        )
        joined["obs"] = {k: np.concatenate([p.obs[k] for p in parts]) for k in parts[0].obs}
        return cls(**joined)


@dataclass(frozen=True)
class LabelCost:
    """What labelling cost: instances, labels by source, hedge searches (scorings), replan solves, CPU seconds of
    the labelling processes and wall seconds of the whole run."""

    instances: int
    hedge_labels: int
    finish_labels: int
    searches: int
    solves: int
    cpu_s: float
    wall_s: float

    @property
    def labels_per_cpu_s(self) -> float:
        return (self.hedge_labels + self.finish_labels) / self.cpu_s if self.cpu_s > 0 else 0.0

    @property
    def cpu_s_per_instance(self) -> float:
        return self.cpu_s / self.instances if self.instances else 0.0


def label_futures(hedge: AnticipatingGuidedSearch, seed: int, step: int, count: int) -> list[FleetState] | None:
    """The ``count`` futures of the label of instance ``seed`` at ``step`` (the hedge's simulator at that step):
    drawn from a generator seeded by both, so the label's futures can be drawn again; None where nothing can come."""
    return hedge.futures_at(np.random.default_rng([FUTURES_STREAM, int(seed), int(step)]), count)


def soft_target(actions: np.ndarray, mean_moves: np.ndarray, temperature: float) -> tuple[np.ndarray, int, float]:
    """([17] float32 q over the candidates' actions, the best candidate's action, the weight 1 - exp(-gap / T)).
    A candidate repeated (fewer allowed headings than asked) counts once; the best is the first of least mean."""
    best_of: dict[int, float] = {}
    for a, m in zip(actions.tolist(), mean_moves.tolist(), strict=True):
        best_of[a] = min(m, best_of.get(a, np.inf))
    acts, means = np.array(list(best_of)), np.array(list(best_of.values()))
    low = means.min()
    q = np.exp(-(means - low) / temperature)
    target = np.zeros(NUM_ACTIONS, np.float64)
    target[acts] = q / q.sum()
    gap = np.sort(means)[1] - low if len(means) > 1 else np.inf
    return target.astype(np.float32), int(actions[int(np.argmin(mean_moves))]), float(1.0 - np.exp(-gap / temperature))


def label_instance(
    policy: GreedyPolicy, demand: str | DemandPrior | DemandModel | None, cfg: EnvConfig, opts: LabelOptions,
    rng: np.random.Generator, seed: int = 0,
) -> Labels:  # fmt: skip
    """The labels of one flight of ``policy``'s greedy decoding (loop guard included) through the world ``cfg``
    (module docstring); ``demand`` is the hedge's (None: the world's family); ``rng`` draws the ``beta`` mixture;
    ``seed`` (the instance's) is recorded and seeds the futures (:func:`label_futures`)."""
    return _label(policy, demand, cfg, opts, rng, seed)[0]


def _label(
    policy: GreedyPolicy, demand: str | DemandPrior | DemandModel | None, cfg: EnvConfig, opts: LabelOptions,
    rng: np.random.Generator, seed: int,
) -> tuple[Labels, int, int]:  # fmt: skip
    """:func:`label_instance`'s labels, and the hedge scorings and the replan solves they took."""
    seed = check_integer("seed", seed, 0, MAX_SEED)
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    # the hedge scores the network's candidates; its own search at reset draws one future (it is not a label)
    hedge = AnticipatingGuidedSearch(
        policy, demand, first_headings=opts.first_headings, futures=1, commit=opts.commit, tail=opts.tail,
        wait_action=opts.wait_action, top_k=1, samples=0,
    )  # fmt: skip
    hedge.reset(env.sim)  # also resets the policy's loop guard: the flight below is its plain greedy decoding
    expert: ReplanExpert | None = None
    rows: list[tuple[Any, ...]] = []  # (obs, target, action, weight, source, promised moves, plan, step)
    searches, closed = 0, False
    while True:
        t = int(env.sim.state.t[0])
        greedy = policy(obs)  # [1, 1]: called once per step, as a plain flight does (its loop guard's memory)
        futures = None if closed else label_futures(hedge, seed, t, opts.futures)
        closed = futures is None
        if futures is not None and t % opts.every == 0:
            rows.append(_hedge_row(hedge.scores_at(futures), _one(obs), opts, t))
            searches += 1
        elif closed:
            expert = expert if expert is not None else ReplanExpert(cfg, 1, opts.finish_beam)
            rows.extend(_finish_row(expert, env, greedy, _one(obs), t))
        action = _flown(greedy, rows[-1][2] if rows and rows[-1][7] == t else None, opts.beta, rng)
        obs, ended = _step(env, action, expert)
        if ended:
            break
    return _stack(rows, seed), searches, (expert.solves if expert is not None else 0)


def _finish_row(
    expert: ReplanExpert, env: VectorEnv, greedy: np.ndarray, obs: dict[str, np.ndarray], t: int
) -> list[tuple[Any, ...]]:  # fmt: skip
    """A finish label's row (none where the solver has no plan): the held plan's first heading, one-hot, weight 1,
    its length the moves promised (the network's ``greedy`` heading kept where it is as short)."""
    first = int(expert.labels(env, proposals=greedy[:, 0])[0])
    if first == NO_LABEL:
        return []
    target = np.zeros(NUM_ACTIONS, np.float32)
    target[first] = 1.0
    plan = list(expert.plans[0])
    return [(obs, target, first, 1.0, FINISH, float(len(plan)), plan, t)]


def _flown(greedy: np.ndarray, label: int | None, beta: float, rng: np.random.Generator) -> np.ndarray:
    """[1, 1] the action flown: the network's, or with probability ``beta`` the label's where there is one."""
    if label is not None and beta > 0 and rng.random() < beta:
        return np.array([[label]], np.int64)
    return greedy


def _step(env: VectorEnv, action: np.ndarray, expert: ReplanExpert | None) -> tuple[dict[str, np.ndarray], bool]:
    """``action`` flown in ``env``, the expert's held plan moved on or dropped: (the observation, the end)."""
    before = released_count(env)
    obs, _, terminated, truncated, _ = env.step(action)
    ended = bool(terminated[0] or truncated[0])
    if expert is not None:
        expert.advance(action[:, 0], released_count(env) > before, np.array([ended]))
    return obs, ended


def _hedge_row(scores: SearchScores, obs: dict[str, np.ndarray], opts: LabelOptions, t: int) -> tuple[Any, ...]:
    """A hedge label's row: the soft target over the candidates, the best one's action held as it would be (the
    wait ``commit`` steps), its mean moves promised."""
    target, label, weight = soft_target(scores.actions, scores.mean_moves, opts.temperature)
    hold = opts.commit if scores.waits[int(np.argmin(scores.mean_moves))] else 1
    return obs, target, label, weight, HEDGE, float(scores.mean_moves.min()), [label] * hold, t


def _one(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: np.array(v[0]) for k, v in obs.items()}


def _stack(rows: list[Any], seed: int) -> Labels:
    width = max((len(r[6]) for r in rows), default=1)
    plan = np.full((len(rows), width), -1, np.int16)
    for i, r in enumerate(rows):
        plan[i, : len(r[6])] = r[6]
    obs = {k: np.stack([r[0][k] for r in rows]) for k in rows[0][0]} if rows else {}
    return Labels(
        obs=obs,
        target=np.array([r[1] for r in rows], np.float32).reshape(-1, NUM_ACTIONS),
        action=np.array([r[2] for r in rows], np.int64),
        weight=np.array([r[3] for r in rows], np.float32),
        source=np.array([r[4] for r in rows], np.int8),
        promised_moves=np.array([r[5] for r in rows], np.float64),
        plan=plan,
        seed=np.full(len(rows), seed, np.int64),
        step=np.array([r[7] for r in rows], np.int64),
    )


def load_labeller(checkpoint_or_name: str | Path) -> GreedyPolicy:
    """The policy a shipped name (``berlin``) or a checkpoint file names."""
    from uamfleet.rl.checkpoint import PRETRAINED
    from uamfleet.rl.policy import load_policy

    if isinstance(checkpoint_or_name, str) and checkpoint_or_name in PRETRAINED:
        from uamfleet.policies.learned import pretrained

        return pretrained(checkpoint_or_name)
    if not Path(checkpoint_or_name).is_file():
        raise FileNotFoundError(
            f"no checkpoint {str(checkpoint_or_name)!r}; give a .pt file or a shipped name {tuple(PRETRAINED)}."
        )
    return load_policy(checkpoint_or_name)[0]


_WORKER: dict[str, Any] = {}


def _start_worker(checkpoint_or_name: str | Path) -> None:
    torch.set_num_threads(1)
    _WORKER["policy"] = load_labeller(checkpoint_or_name)


def _label_seed(job: tuple[str, int, str | None, LabelOptions, str]) -> tuple[int, int, int, int, float]:
    """One instance labelled in a worker and written to ``out_dir/labels_<seed>.npz``: (hedge labels, finish labels,
    searches, solves, CPU seconds)."""
    family, seed, demand, opts, out_dir = job
    start = time.process_time()
    cfg = make_instance(family, seed)
    if opts.wait_action == "hover":
        cfg = cfg.replace(hover_action=True)
    labels, searches, solves = _label(_WORKER["policy"], demand, cfg, opts, np.random.default_rng(seed), seed)
    labels.save(Path(out_dir) / f"labels_{seed}.npz")
    hedge = int((labels.source == HEDGE).sum())
    return hedge, labels.num_labels - hedge, searches, solves, time.process_time() - start


def label_instances(
    checkpoint_or_name: str | Path, family: str, seeds: Sequence[int], demand: str | None, opts: LabelOptions,
    workers: int, out_dir: str | Path,
) -> LabelCost:  # fmt: skip
    """Label the instances ``seeds`` of ``family`` (hover worlds where ``opts.wait_action`` is ``hover``) with the
    network ``checkpoint_or_name`` as the hedge's base, in ``workers`` spawned processes of one torch thread each;
    ``out_dir/labels_<seed>.npz`` per instance (the same files for any number of workers). ``demand`` is the
    hedge's (None: the family's law)."""
    check_family(family)
    workers = check_integer("workers", workers, 1, 256, fix=" (labelling processes, e.g. 2)")
    seeds = [check_integer("seed", s, 0, MAX_SEED) for s in seeds]
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds {seeds} repeat an instance; give each seed once.")
    out = Path(out_dir)
    taken = [s for s in seeds if (out / f"labels_{s}.npz").exists()]
    if taken:
        raise FileExistsError(f"{out / f'labels_{taken[0]}.npz'} exists; give a fresh out_dir.")
    out.mkdir(parents=True, exist_ok=True)
    load_labeller(checkpoint_or_name)  # a bad name or file fails here, not in a worker
    start = time.perf_counter()
    jobs = [(family, s, demand, opts, str(out)) for s in seeds]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(
        workers, mp_context=context, initializer=_start_worker, initargs=(checkpoint_or_name,)
    ) as pool:
        results = list(pool.map(_label_seed, jobs))
    sums = np.array([r[:4] for r in results], np.int64).reshape(-1, 4).sum(0)
    return LabelCost(
        instances=len(seeds), hedge_labels=int(sums[0]), finish_labels=int(sums[1]), searches=int(sums[2]),
        solves=int(sums[3]), cpu_s=float(sum(r[4] for r in results)), wall_s=time.perf_counter() - start,
    )  # fmt: skip


def load_labels(out_dir: str | Path, seeds: Sequence[int]) -> Labels:
    """The labels :func:`label_instances` wrote for ``seeds``, in their order."""
    return Labels.concat([Labels.load(Path(out_dir) / f"labels_{s}.npz") for s in seeds])


__all__ = [
    "FINISH",
    "HEDGE",
    "NUM_ACTIONS",
    "LabelCost",
    "LabelOptions",
    "Labels",
    "label_futures",
    "label_instance",
    "label_instances",
    "load_labeller",
    "load_labels",
    "soft_target",
]
