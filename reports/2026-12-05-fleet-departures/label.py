"""Label departures from the claims policy's plan by re-flying training episodes: at chosen (step, taxi) points the
runner-up action is flown instead of the flown one, everything else as the policy flies, and the episode's cost
(distance + LAMBDA x passenger-seconds of wait) of both is kept with the network's input rows of that taxi at that
step. An episode is deterministic given its instance, so a difference is the exact effect of that one departure.
Also keeps a sample of the episode's other rows (for an anchor to the start). README.md here.

python reports/2026-12-05-fleet-departures/label.py --family berlin --setting 4x48 --first 500000 --count 2 --out a.npz
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uamfleet.cli.fleet_benchmark import dispatcher
from uamfleet.config import FLEET_ARRIVAL_WINDOW_S
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.rl.fleet_claims import with_claims
from uamfleet.rl.fleet_imitation import padded_rows
from uamfleet.rollout import fly
from uamfleet.types import WAITING

CHECKPOINT = "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt"
LAMBDA = 20.0  # m per passenger-second of wait (fleet-finetune's default)
HORIZONS = (10, 30, 100)  # steps after the departure over which the cost is also compared


def cost_over(pol: Departing, t: int, steps: int, slot_s: float) -> float:
    """The fleet's cost over steps t .. t + steps - 1 of a flight (fewer at the episode's end)."""
    end = min(t + steps, len(pol.flown_m) - 1)
    return pol.flown_m[end] - pol.flown_m[t] + LAMBDA * slot_s * sum(pol.waiting[t:end])


class Departing:
    """The claims policy, recording each step's logits and padded rows; at ``departure`` = (step, taxi, action) it
    flies that action instead."""

    def __init__(self, flown, departure=None, record_rows=False) -> None:
        self.flown, self.departure, self.record_rows = flown, departure, record_rows
        self.spec = flown.spec

    def reset(self, sim) -> None:
        self.flown.reset(sim)
        self.sim = sim
        self.logits, self.actions, self.rows = [], [], []
        self.flown_m, self.waiting = [], []  # before each step: the fleet's distance so far, passengers waiting

    def act(self, obs):
        f, s = self.flown, self.sim.state
        self.flown_m.append(float(s.distance_m[0].sum()))
        self.waiting.append(int(np.count_nonzero((s.pax_status[0] == WAITING) & s.pax_exists[0])))
        f.dispatcher.act(obs)
        inputs = with_claims(f.policy.network_input(obs), f.claims())
        logits = f.policy.logits_of(inputs)
        actions = f.policy.choose(obs, logits).copy()
        t = len(self.actions)
        if self.departure is not None and self.departure[0] == t:
            actions[0, self.departure[1]] = self.departure[2]
        self.logits.append(logits.detach().numpy().copy())
        self.actions.append(actions[0].copy())
        if self.record_rows:
            self.rows.append(padded_rows(f.policy, inputs))
        return actions


def cost(traj, cfg) -> dict[str, float]:
    m = episode_metrics(traj, cfg.radio)
    wait_sum = m.awt_s * m.num_requests
    undelivered = m.num_requests - m.delivered
    return {"td_m": m.td_m, "wait_sum_s": wait_sum, "p50": m.wait_p50_s, "p95": m.wait_p95_s,
            "undelivered": undelivered, "cost": m.td_m + LAMBDA * wait_sum + 20_000.0 * undelivered}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--family", default="berlin")
    ap.add_argument("--setting", default="4x48")
    ap.add_argument("--first", type=int, default=500_000, help="first training seed (index into the split)")
    ap.add_argument("--count", type=int, default=1)
    ap.add_argument("--points", type=int, default=40, help="departures per episode")
    ap.add_argument("--near-margin", type=float, default=2.0, help="every point under this margin first")
    ap.add_argument("--max-margin", type=float, default=6.0, help="then random points under this margin")
    ap.add_argument("--anchor-rows", type=int, default=200, help="other rows kept per episode")
    ap.add_argument("--checkpoint", default=CHECKPOINT)
    ap.add_argument("--max-wall-s", type=float, default=1e9)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    taxis, requests = (int(x) for x in a.setting.split("x"))
    name = f"fleet_claims:source={a.checkpoint}"
    start = time.time()
    labelled: list[dict] = []
    anchor: list[dict] = []
    meta: list[
        list[float]
    ] = []  # seed, step, taxi, flown, departure, margin, d_cost, d_td, d_wait, d_p50, d_p95, d_undelivered, d_cost@HORIZONS
    for seed in split_seeds("train", a.count, first=a.first):
        if time.time() - start > a.max_wall_s:
            break
        cfg = make_fleet_instance(a.family, seed, taxis, requests, separation="shield", hover_action=True)
        base_pol = Departing(dispatcher(name, taxis, None, FLEET_ARRIVAL_WINDOW_S), record_rows=True)
        t0 = time.time()
        base = cost(fly(cfg, base_pol), cfg)
        logits, actions = np.stack(base_pol.logits), np.stack(base_pol.actions)  # [T, A, n], [T, A]
        order = np.argsort(-logits, axis=-1)
        top = np.take_along_axis(logits, order[..., :2], -1)
        margin, second = top[..., 0] - top[..., 1], order[..., 1]
        valid = (top[..., 1] > -1e6) & (second != actions) & (margin < a.max_margin)
        rng = np.random.default_rng(seed)
        near = np.argwhere(valid & (margin < a.near_margin))
        far = np.argwhere(valid & (margin >= a.near_margin))
        pts = np.concatenate([near[rng.permutation(len(near))], far[rng.permutation(len(far))]])[: a.points]
        for t, taxi in pts:
            dep = Departing(
                dispatcher(name, taxis, None, FLEET_ARRIVAL_WINDOW_S), (int(t), int(taxi), int(second[t, taxi]))
            )
            c = cost(fly(cfg, dep), cfg)
            horizon = [
                cost_over(dep, int(t), h, cfg.slot_s) - cost_over(base_pol, int(t), h, cfg.slot_s) for h in HORIZONS
            ]
            labelled.append({k: v[taxi] for k, v in base_pol.rows[t].items()})
            meta.append([seed, t, taxi, actions[t, taxi], second[t, taxi], margin[t, taxi],
                         *(c[k] - base[k] for k in ("cost", "td_m", "wait_sum_s", "p50", "p95", "undelivered")), *horizon])  # fmt: skip
        T = len(base_pol.rows)
        for i in rng.choice(T * taxis, size=min(a.anchor_rows, T * taxis), replace=False):
            t, taxi = divmod(int(i), taxis)
            anchor.append({k: v[taxi] for k, v in base_pol.rows[t].items()})
        m = np.asarray(meta)[-len(pts) :] if len(pts) else np.zeros((0, 12))
        print(
            f"{a.family} {a.setting} seed {seed}: {len(pts)} departures ({len(near)} near) in {time.time() - t0:.0f}s;"
            f" better {np.sum(m[:, 6] < 0)}, worse {np.sum(m[:, 6] > 0)}, same {np.sum(m[:, 6] == 0)}",
            flush=True,
        )
    out = {"meta": np.asarray(meta, dtype=np.float64)}
    for prefix, rows in (("x_", labelled), ("anchor_", anchor)):
        for k in rows[0]:
            out[prefix + k] = np.stack([r[k] for r in rows])
    np.savez_compressed(a.out, **out)


if __name__ == "__main__":
    main()
