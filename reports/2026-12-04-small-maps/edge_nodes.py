"""Diagnosis, not a fix: the policy on a map whose outer block centres lie outside it, with those centres moved in.

``uamfleet.paths.distance_table.DistanceTable`` puts a node at each block centre ``(b + 0.5) * block_m`` and joins it
to the nearest flyable raster cell within ``snap_m`` (15 m). On San Francisco (side 920 m, 100 m blocks) the top row
and right column of centres lie at 950 m, 30 m outside the map, so they get no node: a stop in that 20 m strip is
read through its inward corners only, and when those are not flyable the observer sees no path to it (``stop_paths``
at its clip, no progress heading). Here each centre outside the map is clamped onto its edge before the node is
looked up (the gap still measured from the centre), the tables are rebuilt without the disk cache, and the policy
flies a map's validation instances in this process.

    UAMFLEET_CACHE=off PYTHONPATH=$PWD python reports/2026-12-04-small-maps/edge_nodes.py --count 100
"""

from __future__ import annotations

import argparse
import csv
import os

import numpy as np

from uamfleet.instances import make_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.paths import distance_table
from uamfleet.policies import make_named
from uamfleet.rollout import fly

_original_init = distance_table.DistanceTable.__init__


def _init_with_edge_nodes(self, graph, *args, **kwargs):  # type: ignore[no-untyped-def]
    _original_init(self, graph, *args, **kwargs)
    nbx, nby = self.shape
    bx, by = np.divmod(np.arange(nbx * nby), nby)
    centres = np.stack([(bx + 0.5) * self.block_m, (by + 0.5) * self.block_m], axis=-1)
    for i, c in enumerate(centres):
        if self.nodes[i] >= 0:
            continue
        node = graph.nearest_node(np.minimum(c, EDGE_M))
        gap = float(np.hypot(*(graph.node_xy(node) - c)))
        if gap <= graph.snap_m + float(np.max(c - np.minimum(c, EDGE_M))):
            self.nodes[i], self.gap_m[i] = node, gap
    self.distance_m[:] = np.nan
    self.filled[:] = False


EDGE_M = 920.0  # the map's side, set in main


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--map", default="san_francisco")
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--policy", default="learned:source=reports/2026-12-04-map-mixture/mixmaps.pt,idle_wait=true")
    parser.add_argument("--out-csv", default="reports/2026-12-04-small-maps/edge_nodes_sf_val100.csv")
    args = parser.parse_args()
    assert os.environ.get("UAMFLEET_CACHE") == "off", "run with UAMFLEET_CACHE=off: tables are rebuilt here"
    global EDGE_M
    EDGE_M = float(make_instance(args.map, split_seeds("validation", 1)[0]).radio.side_m)
    distance_table.DistanceTable.__init__ = _init_with_edge_nodes  # type: ignore[method-assign]
    policy = make_named(args.policy)
    rows = []
    for seed in split_seeds("validation", args.count):
        cfg = make_instance(args.map, seed, max_passengers=6)
        m = episode_metrics(fly(cfg, policy), cfg.radio, threshold_db=cfg.sinr_min_db)
        rows.append({"instance": seed, "threshold_db": cfg.sinr_min_db, "method": args.policy + " edge nodes",
                     "pr_pct": m.pr_pct, "td_m": m.td_m})  # fmt: skip
        print(seed, m.pr_pct, m.td_m, flush=True)
    with open(args.out_csv, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
