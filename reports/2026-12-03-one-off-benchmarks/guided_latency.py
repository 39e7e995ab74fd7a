"""Latency of guided search at decision time (uamfleet/rl/guided.py) beside the greedy decision it starts from.

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/guided_latency.py --count 20
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/guided_latency.py --family detroit3gpp --count 20 --horizon 60
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/guided_latency.py --count 20 --finish-beam 16   # + the finisher
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/guided_latency.py --count 20 --hedge --trace   # over futures

Flies a shipped policy (``--policy``, the generalist ``berlin`` by default) with guided search on the first ``--count``
test instances of ``--family`` and prints, per search
(at the start and at each release), the wall-clock and the thread CPU seconds: on a machine shared with other jobs the
CPU time is the figure that says what one idle core would take. Torch runs on one thread. With ``--finish-beam`` it
also flies the greedy policy finished by one search once no request can come (uamfleet/baselines/finish.py) and
prints that search's times. With ``--hedge`` the search is :class:`uamfleet.rl.guided.AnticipatingGuidedSearch` (its
searches over sampled futures and its one search once nothing can come, together); ``--trace`` runs the policy's
actor as a TorchScript trace (the same actions, less overhead per call).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

import uamfleet
from uamfleet.baselines.finish import FinishWithSearch
from uamfleet.instances import make_instance, split_seeds
from uamfleet.rl.guided import AnticipatingGuidedSearch, GuidedSearchPolicy
from uamfleet.rollout import fly


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--top-k", type=int, default=8)
    parser.add_argument("--samples", type=int, default=None, help="sampled flights (default: the class's)")
    parser.add_argument("--family", default="berlin", help="instance family (berlin, detroit3gpp, munich)")
    parser.add_argument("--split", default="test", help="instance split (validation, test)")
    parser.add_argument("--feasibility", default="endpoint_block", help="endpoint_block or segment_raster")
    parser.add_argument("--policy", default="berlin", help="a name of uamfleet.pretrained")
    parser.add_argument("--horizon", type=int, default=None, help="GuidedSearchPolicy(horizon=...); none: full")
    parser.add_argument("--finish-beam", type=int, default=0, help="> 0: also the finisher's search of this width")
    parser.add_argument("--hedge", action="store_true", help="AnticipatingGuidedSearch with its default settings")
    parser.add_argument("--trace", action="store_true", help="the policy's actor as a trace (GreedyPolicy.trace_actor)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    policy = uamfleet.pretrained(args.policy)
    if args.trace:
        policy.trace_actor()
    settings = dict(top_k=args.top_k, horizon=args.horizon)
    settings |= {} if args.samples is None else {"samples": args.samples}
    guided = (AnticipatingGuidedSearch(policy, args.family, **settings) if args.hedge
              else GuidedSearchPolicy(policy, **settings))  # fmt: skip
    if args.trace:  # a trace is made at the first call of each batch shape: made before timing, on a train instance
        warm = policy.layout(make_instance(args.family, split_seeds("train", 1)[0], feasibility=args.feasibility))
        guided.fly(warm)
        guided.fly(warm)
    wall, cpu, greedy_cpu, finish_cpu, finish_wall, known_cpu = [], [], [], [], [], []
    for seed in split_seeds(args.split, args.count):
        cfg = policy.layout(make_instance(args.family, seed, feasibility=args.feasibility))
        guided.fly(cfg)
        # the hedge's searches over futures come first (one score each); its last, over the known requests once
        # nothing can come, is timed apart
        hedging = len(guided.scores) if args.hedge else len(guided.plans)
        wall += [p[3] for p in guided.plans[:hedging]]
        cpu += [p[4] for p in guided.plans[:hedging]]
        known_cpu += [p[4] for p in guided.plans[hedging:]]
        start = time.thread_time()
        steps = len(policy.fly(cfg).events)
        greedy_cpu.append((time.thread_time() - start) / max(steps, 1))
        if args.finish_beam:
            finisher = FinishWithSearch.of_family(policy, args.family, cfg.slot_s, beam=args.finish_beam)
            fly(cfg, finisher)
            finish_cpu += [solve[2] for solve in finisher.solves]
            finish_wall += [solve[3] for solve in finisher.solves]
    pct = [50, 95, 100]
    print(
        f"{'hedging' if args.hedge else 'guided'} search{' (traced actor)' if args.trace else ''}, "
        f"{len(cpu)} searches on {args.count} {args.family} {args.split} instances ({args.feasibility}; "
        f"top-k {args.top_k}, "
        f"samples {guided.samples}, horizon {args.horizon}): CPU s p50/p95/max "
        f"{np.percentile(cpu, pct).round(3).tolist()}, wall s {np.percentile(wall, pct).round(3).tolist()}"
    )
    if known_cpu:
        print(
            f"its search once nothing can come, {len(known_cpu)} searches: CPU s p50/p95/max "
            f"{np.percentile(known_cpu, pct).round(3).tolist()}"
        )
    print(
        f"greedy decoding: CPU ms per step (episode mean, incl. the env step) p50/max "
        f"{(1000 * np.percentile(greedy_cpu, [50, 100])).round(2).tolist()}"
    )
    if finish_cpu:
        print(
            f"the finisher's search (beam {args.finish_beam}), {len(finish_cpu)} searches: CPU s p50/p95/max "
            f"{np.percentile(finish_cpu, pct).round(3).tolist()}, "
            f"wall s {np.percentile(finish_wall, pct).round(3).tolist()}"
        )


if __name__ == "__main__":
    main()
