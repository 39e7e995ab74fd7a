"""PettingZoo ParallelEnv face of the batched core (one env slice, E = 1).

Environment
-----------
N air taxis (agents ``uam_0 … uam_{N-1}``) fly at a fixed altitude over one radio map, pick up and drop off
passengers who request rides over time (``seats`` each, 2 by default), and may only fly where the expected
SINR of the block (or of the whole segment, ``feasibility="segment_raster"``) is at or above
``sinr_min_db``. N = 1 with ``scenario="berlin_p4"`` is the MSHA-RL paper's setup.

Action space
------------
``Discrete(16)``: heading k flies one ``step_m`` along 22.5°·k counter-clockwise from east. Moves that leave
the map or break the SINR rule are 0 in ``observation["action_mask"]`` (np.int8); taking one anyway costs a
step in place and the ``blocked`` penalty (never a teleport, never a clamp).

Observation space
-----------------
A ``Dict`` per taxi, tabulated in :class:`UAMFleetParallelEnv` (``self``, ``history``, ``passengers`` with
``passenger_mask``, ``sinr_patch``, ``visit_patch``, ``others`` with ``others_mask``, ``action_mask``);
``state()`` returns the global state for centralised critics (``state_space``), tabulated there too. The rules
behind every field: ``docs/rules.md``.

Rewards
-------
Per taxi, the sum of named terms (:data:`uamfleet.config.REWARD_TERMS`), each weighted by the
:class:`RewardConfig` field of its name: ``step``, ``explore`` (first visit of a block, ``explore_repeat`` per
repeat visit), ``pickup``, ``dropoff``, ``blocked``, optional potential-based ``shaping`` (docs/rules.md,
"Rewards").
``infos[agent]["reward_terms"]`` holds this step's terms; at an episode's end ``infos[agent]["episode"]``
holds the per-term episode sums, return, length, delivered count and distance.

Episode end
-----------
Terminated when every passenger of the instance is delivered; truncated at ``time_limit_steps`` (or when a
taxi visits a block more than ``max_block_visits`` times). Both flags are set for all agents at once; the
agent list is then empty until ``reset``.

Arguments
---------
``parallel_env(scenario="berlin_p4", render_mode=None, **overrides)``: any :class:`uamfleet.config.EnvConfig`
field as a keyword (``sinr_min_db``, ``num_taxis``, ``starts_m``, ``requests``, ``radio``, ...).
``render_mode="rgb_array"`` returns matplotlib frames; ``"human"`` opens a live meshcat viewer in the browser
(closed, with its server, by ``close()``).

Seeding
-------
``reset(seed=s)`` makes the episode (random starts and demand) a function of ``s``; ``reset()`` without a seed
continues the generator. The batched core's env e seeded with ``s`` runs the same episodes as this env seeded
with ``s + e``.
"""

from __future__ import annotations

import functools
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from uamfleet.config import REWARD_TERMS, EnvConfig, make_config
from uamfleet.env.vector_env import VectorEnv

AgentID = str


class UAMFleetParallelEnv(ParallelEnv[AgentID, dict[str, np.ndarray], int]):
    """PettingZoo ParallelEnv of one env of the batched core (see the module docstring for the sections).

    Observation of each agent (``observation_space(agent)``), P = passenger slots, k = ``patch_size``,
    H = ``history_len``, A = ``num_taxis``; positions relative to the taxi and divided by the map side:

    ==================  ================  =======  ====  =====================================================
    field               shape             dtype    unit  meaning
    ==================  ================  =======  ====  =====================================================
    ``self``            (4,)              float32  --    x, y (/ side), free seats (/ seats), t / time limit
    ``history``         (H, 3)            float32  --    last H positions - current (/ side), free seats then
    ``passengers``      (P, 12)           float32  --    ``uamfleet.types.PASSENGER_FEATURES``; 0 while hidden
    ``passenger_mask``  (P,)              int8     --    1 = released request
    ``sinr_patch``      (k, k)            float32  dB    block SINR - threshold around the taxi, in [-30, 30]
    ``visit_patch``     (k, k)            float32  --    this taxi's visits of those blocks / max(t, 1), <= 1
    ``others``          (max(A-1, 1), 3)  float32  --    other taxis: dx, dy (/ side), free seats (/ seats)
    ``others_mask``     (max(A-1, 1),)    int8     --    1 = a real other taxi
    ``action_mask``     (16,)             int8     --    1 = heading allowed
    ==================  ================  =======  ====  =====================================================

    ``state()``: float32 [4 A + 9 P + 1], in this order:

    ==========  ======  =======  ====  ==========================================================================
    part        shape   dtype    unit  meaning
    ==========  ======  =======  ====  ==========================================================================
    taxis       (A, 4)  float32  --    x, y (/ side, absolute), free seats (/ seats), taxi index / A
    passengers  (P, 9)  float32  --    origin x, y, destination x, y (/ side), status one-hot (waiting, on
                                       board, delivered), (carrier + 1) / A, (t - release) / time limit; 0 while
                                       hidden
    time        (1,)    float32  --    t / time limit, <= 1
    ==========  ======  =======  ====  ==========================================================================

    Units and the rules behind each field: ``docs/rules.md`` ("Observation", "State").
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "uamfleet_v0",
        "render_modes": ["rgb_array", "human"],
        "is_parallelizable": True,
        "render_fps": 5,
    }

    def __init__(self, cfg: EnvConfig, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of {self.metadata['render_modes']} or None."
            )
        self.cfg = cfg
        self.render_mode = render_mode
        self.core = VectorEnv(cfg, num_envs=1, autoreset=False)
        self.possible_agents = [f"uam_{i}" for i in range(cfg.num_taxis)]
        self.agents: list[AgentID] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self._obs_space = self.core.single_observation_space
        self._act_space = self.core.single_action_space
        self.state_space = self.core.state_space
        self._trails: list[np.ndarray] = []
        self._viewer: Any = None  # the meshcat FleetViewer of render_mode="human", opened by the first render()

    # PettingZoo requires the identical space object on every call.
    def observation_space(self, agent: AgentID) -> spaces.Space:
        return self._obs_space

    def action_space(self, agent: AgentID) -> spaces.Space:
        return self._act_space

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[AgentID, dict[str, np.ndarray]], dict[AgentID, dict[str, Any]]]:
        obs, _ = self.core.reset(seed=seed)
        self.agents = list(self.possible_agents)
        self._trails = [self.core.state.pos_m[0].copy()]
        return self._split(obs), {agent: {} for agent in self.agents}

    def step(self, actions: dict[AgentID, int]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("step() called with no live agents: call reset() first.")
        missing = [a for a in self.agents if a not in actions]
        unknown = [a for a in actions if a not in self._index]
        if missing or unknown:
            raise ValueError(
                f"actions must have one entry per live agent {self.agents}; missing {missing}, unknown {unknown}."
            )
        batch = np.array([[int(actions[a]) for a in self.possible_agents]], dtype=np.int64)
        obs, rewards, terminated, truncated, info = self.core.step(batch)
        self._trails.append(self.core.state.pos_m[0].copy())
        agents = self.agents
        terms = info["reward_terms"][0]  # [A, T]
        infos: dict[AgentID, dict[str, Any]] = {}
        for agent in agents:
            i = self._index[agent]
            infos[agent] = {"reward_terms": dict(zip(REWARD_TERMS, terms[i].tolist(), strict=True))}
            if "episode" in info:
                ep = info["episode"]
                infos[agent]["episode"] = {
                    key: (float(v[0, i]) if v.ndim == 2 else float(v[0])) for key, v in ep.items()
                }
        out_obs = self._split(obs)
        out_rew = {a: float(rewards[0, self._index[a]]) for a in agents}
        out_term = dict.fromkeys(agents, bool(terminated[0]))
        out_trunc = dict.fromkeys(agents, bool(truncated[0]))
        if terminated[0] or truncated[0]:
            self.agents = []
        return out_obs, out_rew, out_term, out_trunc, infos

    def _split(self, obs: dict[str, np.ndarray]) -> dict[AgentID, dict[str, np.ndarray]]:
        # Views, not copies: the core returns fresh arrays every step and never writes into them again.
        return {agent: {k: v[0, self._index[agent]] for k, v in obs.items()} for agent in self.agents}

    def state(self) -> np.ndarray:
        return self.core.global_state()[0]

    def render(self) -> np.ndarray | None:
        """``"rgb_array"``: an RGB frame [H, W, 3] uint8 (matplotlib). ``"human"``: opens a meshcat viewer in
        the browser on the first call (its address is printed) and shows the current state; returns None."""
        if self.render_mode is None:
            return None
        if self.render_mode == "human":
            self._render_human()
            return None
        from uamfleet.viz.figures import render_frame

        return render_frame(self.core.world, self.core.state, np.stack(self._trails, axis=1))

    def _render_human(self) -> None:
        if self._viewer is None:
            from uamfleet.viz.meshcat_view import FleetViewer

            world = self.core.world
            title = f"{self.cfg.scenario} · {self.cfg.num_taxis} taxi(s) · γ_T = {world.threshold_db:g} dB (live)"
            self._viewer = FleetViewer(world.radio, world.threshold_db, open_server=True, title=title)
        s = self.core.state
        self._viewer.update_live(
            s.pos_m[0], s.pax_status[0], s.pax_origin_m[0], s.pax_dest_m[0], int(s.t[0]),
            pax_taxi=s.pax_taxi[0], seats=self.cfg.seats,
        )  # fmt: skip

    def close(self) -> None:
        """Close the meshcat viewer (and kill its server) if ``render()`` opened one."""
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None


def parallel_env(
    scenario: str | EnvConfig = "berlin_p4", render_mode: str | None = None, **overrides: Any
) -> UAMFleetParallelEnv:
    """The PettingZoo parallel env of a scenario (see :data:`uamfleet.SCENARIOS`) with config overrides."""
    return UAMFleetParallelEnv(make_config(scenario, **overrides), render_mode=render_mode)


@functools.wraps(parallel_env)
def env(**kwargs: Any) -> Any:
    """The AEC version (PettingZoo's ``parallel_to_aec``)."""
    from pettingzoo.utils.conversions import parallel_to_aec

    return parallel_to_aec(parallel_env(**kwargs))
