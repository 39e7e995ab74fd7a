"""Fly the knob controller: ``heading=onward`` whose knobs (wait weight, price of the learned value) are set every
``every`` steps by the ridge model ``fit.py --save`` wrote, from :func:`features.features` of the state now (no
rollout, no future). Knob 0 everywhere flies exactly as onward does.

usage: KNOB_MODEL=/tmp/kc/model.npz python reports/2026-12-05-knob-controller/fly.py <fleet-bench arguments> \
    --dispatchers knob_controller
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "2026-12-05-fleet-foresight"))

from features import features
from fit import choose, expand, predict
from oracle_search import BASES

from uamfleet.cli import fleet_benchmark
from uamfleet.env.protocol import PolicyBase
from uamfleet.policies import make_flown
from uamfleet.policies.registry import register

KNOBS = [(1.0, 100.0), (0.0, 100.0), (3.0, 100.0), (1.0, 0.0), (1.0, 300.0)]  # label.py's order


class KnobController(PolicyBase):
    def __init__(self, base, model_path: str, every: int, margin: float | None) -> None:
        self.base, self.every = base, every
        m = np.load(model_path)
        self.model = m["W"], m["mu"], m["sd"]
        self.margin = float(m["margin"]) if margin is None else margin
        self.interact = bool(m["interact"]) if "interact" in m else False
        self.base_value = base.value

    def reset(self, sim) -> None:
        self.sim = sim
        self.base.wait_weight, self.base.value = KNOBS[0][0], self.base_value
        self.base.reset(sim)

    def act(self, obs):
        s = self.sim.state
        if int(s.t[0]) % self.every == 0:
            state = {name: getattr(s, name)[0] for name in s._fields}
            x = features(state, self.base.routes, self.sim.cfg.time_limit_steps, self.sim.cfg.slot_s,
                         float(self.sim.world.arrays.side_m))  # fmt: skip
            k = int(choose(predict(self.model, expand(x[None], self.interact)), self.margin)[0])
            weight, price = KNOBS[k]
            self.base.wait_weight, self.base.value = weight, self.base_value.with_price(price)
        return self.base.act(obs)


@dataclass(frozen=True)
class ControllerOptions:
    every: int = 10
    margin: float = -1.0  # < 0: the model file's


register(
    "knob_controller", "dispatcher", ControllerOptions,
    lambda o, _b: KnobController(make_flown(BASES["onward"]), os.environ["KNOB_MODEL"], o.every,
                                 None if o.margin < 0 else o.margin),
)  # fmt: skip

if __name__ == "__main__":
    sys.exit(fleet_benchmark.cli(sys.argv[1:]))
