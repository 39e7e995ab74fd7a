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
step in place and the ``blocked`` penalty (never a teleport, never a clamp). ``Discrete(17)`` with
``hover_action=True`` (the ``*_fleet`` presets): action 16 hovers (stays in place, always allowed, not in the mask).

Observation space
-----------------
A ``Dict`` per taxi, tabulated in :class:`UAMFleetParallelEnv` (``self``, ``history``, ``passengers`` with
``passenger_mask``, ``sinr_patch``, ``visit_patch``, ``others`` with ``others_mask``, ``action_mask``, and the
stop fields of ``stop_features`` / ``stop_rivals`` / ``stop_claims``). What a taxi observes is an observer spec
(:class:`uamfleet.observe.spec.ObserverSpec`, ``observer=``). The default observer is the scenario's: the
paper's observation for ``berlin_p4``, ``detroit_p5`` and the ``*_random`` scenarios (``ObserverSpec()``: history
3, every passenger row, 10 x 10 patches, no stop fields), the stop features for ``*_instances``
(``stops=StopsSpec()``) and the stop features with claims for ``*_fleet`` (``stops=StopsSpec(claims=True)``); the
observer fields given as keywords (``patch_size=5``, ``stop_features=True``, ...) change it as they always did. A
spec that cannot read the world is refused in one line (:meth:`~uamfleet.observe.spec.ObserverSpec.reads`).
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
``parallel_env(scenario="berlin_p4", render_mode=None, observer=None, **overrides)``: any
:class:`uamfleet.config.EnvConfig` field as a keyword (``sinr_min_db``, ``num_taxis``, ``starts_m``, ``requests``,
``radio``, ...); ``observer``: an :class:`~uamfleet.observe.spec.ObserverSpec` in place of the scenario's
observer fields.
``render_mode="rgb_array"`` returns matplotlib frames; ``"human"`` opens a live meshcat viewer in the browser
(closed, with its server, by ``close()``). The env draws nothing itself: ``render()`` asks a :class:`Renderer`
made by ``renderer(render_mode, env)`` (``UAMFleetParallelEnv(cfg, render_mode, renderer=...)``), by default
:func:`uamfleet.viz.render.make_renderer`, which ``import uamfleet`` registers.

Seeding
-------
``reset(seed=s)`` makes the episode (random starts and demand) a function of ``s``; ``reset()`` without a seed
continues the generator. The batched core's env e seeded with ``s`` runs the same episodes as this env seeded
with ``s + e``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, ClassVar, Protocol

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from uamfleet.config import REWARD_TERMS, EnvConfig, WorldConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.observe.spec import ObserverSpec
from uamfleet.presets import make_config
from uamfleet.sim.dynamics import check_action

AgentID = str


class Renderer(Protocol):
    """Draws a :class:`UAMFleetParallelEnv` for one ``render_mode``: an RGB frame [H, W, 3] uint8 for
    ``"rgb_array"``, None for ``"human"`` (a window). Made by the env's renderer factory on the first
    ``render()``; ``close()`` frees what it holds (a window, a server)."""

    def render(self, env: UAMFleetParallelEnv) -> np.ndarray | None: ...

    def close(self) -> None: ...


RendererFactory = Callable[[str, "UAMFleetParallelEnv"], Renderer]
"""``(render_mode, env) -> Renderer``."""


class UAMFleetParallelEnv(ParallelEnv[AgentID, dict[str, np.ndarray], int]):
    """PettingZoo ParallelEnv of one env of the batched core (see the module docstring for the sections).

    Observation of each agent (``observation_space(agent)``), P = passenger slots, k = ``patch_size``,
    H = ``history_len``, A = ``num_taxis``; positions relative to the taxi and divided by the map side. P is every
    request of the episode, or with ``passenger_window=K`` K rows per taxi: its riders (request order), then the
    waiting requests nearest to it (feasible-path distance to the origin with ``stop_features``, else straight
    line; ties by request index), then empty rows (docs/rules.md "Passenger window"); ``state()``'s P is always
    every request. The spec of
    every field (bounds, column names, how a learner treats it): :func:`uamfleet.observe.spec.observation_layout`;
    the column names in the meanings are its ``columns``. The last five fields are there with the config flags
    their meaning starts with (the ``*_instances`` scenarios: ``stop_features``; ``*_fleet``: ``stop_claims``):

    ======================  ================  =======  =====  ========================================================
    field                   shape             dtype    unit   meaning
    ======================  ================  =======  =====  ========================================================
    ``self``                (4,)              float32  --     x, y (/ side), free_seats (/ seats), time (t / limit)
    ``history``             (H, 3)            float32  --     the last H steps: dx, dy (then - now, / side),
                                                              free_seats then (/ seats)
    ``passengers``          (P, 12)           float32  --     ``uamfleet.types.PASSENGER_FEATURES``; 0 while hidden
    ``passenger_mask``      (P,)              int8     --     1 = released request
    ``sinr_patch``          (k, k)            float32  dB     block SINR - threshold around the taxi, in [-30, 30]
    ``visit_patch``         (k, k)            float32  --     this taxi's visits of those blocks / max(t, 1), <= 1
    ``others``              (max(A-1, 1), 3)  float32  --     other taxis: dx, dy (/ side), free_seats (/ seats)
    ``others_mask``         (max(A-1, 1),)    int8     --     1 = a real other taxi
    ``action_mask``         (16,)             int8     --     1 = heading allowed
    ``stop_paths``          (P, 3)            float32  sides  stop_features: feasible-path distances path_to_stop,
                                                              ride_path, tour_via_stop (/ side, <= 16)
    ``stop_heading_mask``   (P, 16)           int8     --     stop_features: one-hot, the heading that makes most
                                                              progress toward the row's stop (0: no stop)
    ``stop_rivals``         (P, 2)            float32  sides  stop_rivals or stop_claims: rival_path (<= 16),
                                                              rivals_nearer (a share)
    ``stop_claims``         (P, 2)            int8     --     stop_claims: nearest-first matching, claimed_by_me,
                                                              claimed_by_other
    ``hover_heading_mask``  (16,)             int8     --     stop_claims: one-hot, the allowed heading back toward
                                                              where the taxi was a step ago
    ``heading_lookahead``   (16,)             float32  moves  heading_lookahead: per heading, its move plus the
                                                              shortest tour after it, above the best heading's
    ======================  ================  =======  =====  ========================================================

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
    default_renderer: ClassVar[RendererFactory | None] = None
    """The renderer factory used when none is passed. The env draws nothing itself (drawing lives above it, in
    :mod:`uamfleet.viz`): ``import uamfleet`` registers :func:`uamfleet.viz.render.make_renderer` here."""

    def __init__(
        self,
        cfg: WorldConfig,
        render_mode: str | None = None,
        renderer: RendererFactory | None = None,
        observer: ObserverSpec | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of {self.metadata['render_modes']} or None."
            )
        factory = renderer if renderer is not None else type(self).default_renderer
        if render_mode is not None and factory is None:
            raise ValueError(
                f"render_mode={render_mode!r} needs a renderer: pass renderer=uamfleet.viz.render.make_renderer "
                "(import uamfleet registers it as the default)."
            )
        self.render_mode = render_mode
        self._make_renderer = factory
        self.core = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer)
        self.cfg: EnvConfig = (
            self.core.cfg
        )  # the world joined with what it observes (the given config without observer)
        self.spec = self.core.spec  # what each taxi observes
        self.possible_agents = [f"uam_{i}" for i in range(cfg.num_taxis)]
        self.agents: list[AgentID] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self._live = frozenset(self.possible_agents)
        self._at = [(agent, (0, i)) for i, agent in enumerate(self.possible_agents)]  # (agent, its [E, A] index)
        # the actions of a step: the core reads them during the step only (it keeps no events of the face's steps)
        self._batch = np.zeros((1, cfg.num_taxis), np.int64)
        self._obs_space = self.core.single_observation_space
        self._act_space = self.core.single_action_space
        self.state_space = self.core.state_space
        self._trails: list[np.ndarray] = []  # [A, 2] positions of every step so far, kept only when rendering
        self._viewer: Renderer | None = None  # made by the first render() (for "human": the meshcat viewer)

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
        if self.render_mode is not None:
            self._trails = [self.core.state.pos_m[0].copy()]
        return self._split(obs), {agent: {} for agent in self.agents}

    def step(self, actions: dict[AgentID, int]) -> tuple[dict, dict, dict, dict, dict]:
        agents = self.agents
        if not agents:
            raise RuntimeError("step() called with no live agents: call reset() first.")
        if actions.keys() != self._live:  # agents live and die together: live = all possible agents
            missing = [a for a in agents if a not in actions]
            unknown = [a for a in actions if a not in self._index]
            raise ValueError(
                f"actions must have one entry per live agent {agents}; missing {missing}, unknown {unknown}."
            )
        n, batch = self.cfg.num_actions, self._batch
        row = batch[0]
        for i, agent in enumerate(agents):
            row[i] = _action(actions[agent], i, agent, n)
        # no events: the face returns none, and making them for Python costs more than the step
        obs, rewards, terminated, truncated, info = self.core.step(batch, events=False)
        if self.render_mode is not None:
            self._trails.append(self.core.state.pos_m[0].copy())
        infos = _agent_infos(agents, info)
        out_obs = self._split(obs)
        out_rew = dict(zip(agents, rewards[0].tolist(), strict=True))
        ended = bool(terminated[0]), bool(truncated[0])
        out_term, out_trunc = dict.fromkeys(agents, ended[0]), dict.fromkeys(agents, ended[1])
        if ended[0] or ended[1]:
            self.agents = []
        return out_obs, out_rew, out_term, out_trunc, infos

    def _split(self, obs: dict[str, np.ndarray]) -> dict[AgentID, dict[str, np.ndarray]]:
        # Views, not copies: the core returns fresh arrays every step and never writes into them again.
        return {agent: {k: v[at] for k, v in obs.items()} for agent, at in self._at}

    def state(self) -> np.ndarray:
        return self.core.global_state()[0]

    @property
    def trails_m(self) -> np.ndarray:
        """[A, T + 1, 2] the positions each taxi has been at this episode (kept when ``render_mode`` is set)."""
        return np.stack(self._trails, axis=1)

    def render(self) -> np.ndarray | None:
        """``"rgb_array"``: an RGB frame [H, W, 3] uint8 (matplotlib). ``"human"``: opens a meshcat viewer in
        the browser on the first call (its address is printed) and shows the current state; returns None."""
        if self.render_mode is None:
            return None
        if self._viewer is None:
            assert self._make_renderer is not None  # checked in __init__
            self._viewer = self._make_renderer(self.render_mode, self)
        return self._viewer.render(self)

    def close(self) -> None:
        """Close what ``render()`` opened (the meshcat viewer and its server for ``"human"``)."""
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None


def parallel_env(
    scenario: str | WorldConfig = "berlin_p4",
    render_mode: str | None = None,
    observer: ObserverSpec | None = None,
    **overrides: Any,
) -> UAMFleetParallelEnv:
    """The PettingZoo parallel env of a scenario (see :data:`uamfleet.SCENARIOS`) with config overrides, observed by
    ``observer`` (None: the scenario's observer)."""
    return UAMFleetParallelEnv(face_config(scenario, overrides), render_mode=render_mode, observer=observer)


def face_config(scenario: str | WorldConfig, overrides: dict[str, Any]) -> WorldConfig:
    """The config a face is built from: a bare world without overrides as it is (observed by ``ObserverSpec()``
    unless an observer is given), else :func:`~uamfleet.presets.make_config`'s."""
    if isinstance(scenario, WorldConfig) and not isinstance(scenario, EnvConfig) and not overrides:
        return scenario
    return make_config(scenario, **overrides)


@functools.wraps(parallel_env)
def env(**kwargs: Any) -> Any:
    """The AEC version (PettingZoo's ``parallel_to_aec``)."""
    from pettingzoo.utils.conversions import parallel_to_aec

    return parallel_to_aec(parallel_env(**kwargs))


def _action(value: Any, taxi: int, agent: str, num_actions: int) -> int:
    """One agent's action; a plain int in range takes the fast path, anything else the one rule (check_action)."""
    if type(value) is int and 0 <= value < num_actions:
        return value
    return check_action(value, f"env 0, taxi {taxi} ({agent})", num_actions)


def _agent_infos(agents: list[AgentID], info: dict[str, Any]) -> dict[AgentID, dict[str, Any]]:
    """The core's info of env 0 per agent: its reward terms, and its episode statistics when the episode ended.
    One conversion per array, then plain Python per agent (agent i is taxi i; agents == possible_agents)."""
    terms = info["reward_terms"][0].tolist()  # [A][T]
    infos: dict[AgentID, dict[str, Any]] = {
        agent: {"reward_terms": dict(zip(REWARD_TERMS, row, strict=True))}
        for agent, row in zip(agents, terms, strict=True)
    }
    if "episode" in info:
        for key, v in info["episode"].items():
            per_agent = v[0].tolist() if v.ndim == 2 else [v[0].item()] * len(agents)
            for agent, value in zip(agents, per_agent, strict=True):
                infos[agent].setdefault("episode", {})[key] = float(value)
    return infos
