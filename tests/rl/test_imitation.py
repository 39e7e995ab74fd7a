"""Learning from the search: the heading residual (zero: exactly the prior's choice; large: any allowed heading),
the expert's labels (one solve labels a whole plan, which replays to the distance it promised; a deviation or a
release costs a new solve), and one DAgger fit that moves the policy toward the expert's headings."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import brute_force_moves, small_config

from uamfleet.baselines.step_planner import SearchSettings, StepSearch
from uamfleet.config import Request, heading_vectors
from uamfleet.env.vector_env import VectorEnv
from uamfleet.presets import make_config
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.experts import NO_LABEL, AnticipatingExpert, ReplanExpert
from uamfleet.rl.heads import LOOKAHEAD_RULE, PRIOR_FLOOR
from uamfleet.rl.imitation import Group, ImitationArgs, collect, fit, with_heading_residual
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, obs_to_torch, observed_inputs
from uamfleet.rl.trainer import GreedyPolicy
from uamfleet.types import HIDDEN, NUM_HEADINGS

OPEN_7 = "\n".join(["......."] * 7)


def _berlin_batch(steps: int = 12) -> tuple[VectorEnv, dict[str, torch.Tensor]]:
    """Observations of 8 Berlin instance envs after a few random allowed moves (several stops actionable)."""
    venv = VectorEnv(make_config("berlin_instances", sinr_min_db=-5.0), num_envs=8)
    obs, _ = venv.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        allowed = obs["action_mask"][:, 0].astype(bool)
        obs, *_ = venv.step(np.array([[rng.choice(np.flatnonzero(a))] for a in allowed]))
    return venv, obs_to_torch({k: v.reshape(8, *v.shape[2:]) for k, v in obs.items()}, "cpu")


def _nets(**kw: object) -> tuple[MSHAActorCritic, MSHAActorCritic, VectorEnv, dict[str, torch.Tensor]]:
    venv, obs = _berlin_batch()
    torch.manual_seed(0)
    inputs = observed_inputs(venv.single_observation_space.spaces, "de_msfea", "stops")
    cfg = NetConfig(variant="de_msfea", d_model=32, action_head="stops", **inputs, **kw)  # type: ignore[arg-type]
    prior = MSHAActorCritic(venv.single_observation_space, cfg)
    residual = MSHAActorCritic(venv.single_observation_space, NetConfig(**{**cfg.__dict__, "heading_residual": True}))
    missing, unexpected = residual.load_state_dict(prior.state_dict(), strict=False)
    assert not unexpected and missing and all(k.startswith("stop_head.residual_") for k in missing)
    return prior, residual, venv, obs


def test_zero_residual_flies_exactly_as_the_prior() -> None:
    prior, residual, _, obs = _nets()
    with torch.no_grad():
        p_logits, r_logits = prior.masked_logits(obs), residual.masked_logits(obs)
        torch.testing.assert_close(residual.prior_logits(obs), p_logits, atol=0, rtol=0)
    assert torch.equal(p_logits.argmax(-1), r_logits.argmax(-1))
    # the floor moves at most 16 e^-12 of probability onto headings the prior rules out
    torch.testing.assert_close(r_logits.softmax(-1), p_logits.softmax(-1), atol=16 * np.exp(PRIOR_FLOOR), rtol=0)
    assert float(p_logits.softmax(-1).max(-1).values.min()) > 0.5  # the prior is decided: the test is not vacuous


def test_a_residual_reaches_any_allowed_heading_and_never_a_forbidden_one() -> None:
    _, residual, _, obs = _nets()
    with torch.no_grad():
        chosen = residual.masked_logits(obs).argmax(-1)  # [B] the prior's headings
        allowed = obs["action_mask"] > 0.5  # [B, 16]
        b = int(torch.nonzero(allowed.sum(-1) >= 2)[0, 0])
        other = int(next(h for h in torch.nonzero(allowed[b])[:, 0].tolist() if h != int(chosen[b])))
        forbidden = torch.nonzero(~allowed[b])[:, 0].tolist()
        residual.stop_head.residual_free.bias.zero_()
        residual.stop_head.residual_free.bias[other] = -PRIOR_FLOOR + 5.0  # past the floor and the prior's lead
        for h in forbidden:
            residual.stop_head.residual_free.bias[h] = 100.0
        after = residual.masked_logits(obs)
    assert int(after[b].argmax()) == other
    assert float(after.softmax(-1)[~allowed].max()) == 0.0


def test_heading_residual_needs_the_stop_head() -> None:
    with pytest.raises(ValueError, match="heading_residual"):
        NetConfig(variant="de_msfea", action_head="headings", heading_residual=True)


def _flown(venv: VectorEnv, expert: ReplanExpert, deviate_at: int | None = None) -> tuple[float, int]:
    """Fly the expert's labels (a forced other heading at step ``deviate_at``); (distance flown m, steps)."""
    venv.reset(seed=0)
    released = ((venv.state.pax_status != HIDDEN) & venv.state.pax_exists).sum(-1)
    for t in range(venv.cfg.time_limit_steps):
        label = expert.labels(venv)
        assert label[0] != NO_LABEL
        action = label.copy()
        if t == deviate_at:
            allowed = np.flatnonzero(venv.state.action_mask[0, 0])
            action[0] = next(h for h in allowed if h != label[0])
        _, _, terminated, truncated, info = venv.step(action[:, None])
        now = ((venv.state.pax_status != HIDDEN) & venv.state.pax_exists).sum(-1)
        expert.advance(action, now != released, terminated | truncated)
        released = now
        if terminated[0] or truncated[0]:
            return float(info["episode"]["distance_m"][0].sum()), t + 1
    raise AssertionError("the expert did not finish")


def test_one_solve_labels_a_whole_plan_that_replays_to_the_distance_it_promised() -> None:
    requests = (Request(0, (380.0, 560.0), (600.0, 330.0)), Request(0, (230.0, 400.0), (470.0, 420.0)))
    cfg = small_config(OPEN_7, starts_m=((110.0, 620.0),), requests=requests, time_limit_steps=40)
    venv = VectorEnv(cfg, 1, autoreset=False)
    venv.reset(seed=0)
    promised = StepSearch(cfg).solve(venv.state, [SearchSettings(beam=32, rank_slack=0.5)])
    assert promised is not None and promised.moves >= 4
    expert = ReplanExpert(cfg, 1, beam=32)
    distance, steps = _flown(venv, expert)
    assert distance == promised.moves * cfg.step_m and steps == promised.steps
    assert expert.solves == 1  # every later step was labelled by the same plan


def test_a_release_and_a_deviation_each_cost_one_solve() -> None:
    requests = (Request(0, (380.0, 560.0), (600.0, 130.0)), Request(6, (230.0, 300.0), (470.0, 420.0)))
    cfg = small_config(OPEN_7, starts_m=((110.0, 620.0),), requests=requests, time_limit_steps=60)
    venv = VectorEnv(cfg, 1, autoreset=False)
    expert = ReplanExpert(cfg, 1, beam=32)
    _flown(venv, expert)
    assert expert.solves == 2  # the start and the release at step 6
    expert = ReplanExpert(cfg, 1, beam=32)
    _flown(venv, expert, deviate_at=2)
    assert expert.solves == 3


def test_dagger_fit_moves_the_policy_toward_the_expert() -> None:
    """Collect the expert's own flights (beta 1) on Berlin instance envs and fit: the greedy policy agrees with
    the expert's headings on more of those states than before."""
    cfg = make_config("berlin_instances", sinr_min_db=-5.0, time_limit_steps=200)
    venv = VectorEnv(cfg, num_envs=4)
    obs, _ = venv.reset(seed=1)
    torch.manual_seed(0)
    net = MSHAActorCritic(
        venv.single_observation_space,
        NetConfig(
            variant="de_msfea",
            d_model=16,
            num_heads=2,
            action_head="stops",
            heading_residual=True,
            **observed_inputs(venv.single_observation_space.spaces, "de_msfea", "stops"),
        ),
    )
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    normalizer = ObservationNormalizer(shapes)
    normalizer.update({k: v.reshape(4, *v.shape[2:]) for k, v in obs.items()})
    policy = GreedyPolicy(net, normalizer, torch.device("cpu"), shapes, 1, cfg.num_passengers, cfg)
    group = Group(venv, ReplanExpert(cfg, 4, beam=16), obs, np.zeros(4, np.int64))
    rng = np.random.default_rng(0)
    data = collect([group], policy, beta=1.0, steps=25, rng=rng)
    assert len(data) >= 50 and group.expert.solves >= 4
    x, y, corrected = data.arrays()
    assert len(corrected) == len(y)

    def agreement() -> float:
        with torch.no_grad():
            return float((net.masked_logits(obs_to_torch(x, "cpu")).argmax(-1).numpy() == y).mean())

    before = agreement()
    args = ImitationArgs.from_flat(dict(epochs=30, minibatch=64, learning_rate=3e-3))
    stats = fit(net, data, args, torch.optim.Adam(net.parameters(), lr=3e-3), rng)
    assert agreement() > max(before, 0.5) and stats["bc_agreement"] > before
    assert (y >= 0).all() and (y < NUM_HEADINGS).all()


def test_with_heading_residual_keeps_the_policy() -> None:
    import uamfleet

    policy = uamfleet.pretrained("berlin_stops")
    flying = with_heading_residual(policy)
    assert flying.net.cfg.heading_residual
    _, obs = _berlin_batch(steps=3)
    raw = {k: v.numpy().reshape(8, 1, *v.shape[1:]) for k, v in obs.items()}
    assert np.array_equal(policy(raw), flying(raw))


def test_a_proposal_is_kept_exactly_when_brute_force_says_it_is_as_short() -> None:
    """Every allowed first heading proposed in turn from the start of a tiny instance: the expert keeps the
    proposal as its label if and only if a brute-force search of every move sequence finds no shorter flight
    than the one that starts with it."""
    start = (110.0, 620.0)
    requests = (Request(0, (380.0, 560.0), (600.0, 330.0)), Request(0, (230.0, 400.0), (470.0, 420.0)))
    cfg = small_config(OPEN_7, starts_m=(start,), requests=requests, time_limit_steps=40)
    venv = VectorEnv(cfg, 1, autoreset=False)
    venv.reset(seed=0)
    rules = (cfg.side_m, cfg.step_m, cfg.radius_m, cfg.seats)
    optimum = brute_force_moves(start, requests, *rules, max_moves=7)
    assert optimum == 5
    kept = []
    for heading in np.flatnonzero(venv.state.action_mask[0, 0]):
        child = np.asarray(start) + cfg.step_m * heading_vectors()[heading]
        stops = [p for r in requests for p in (r.origin_m, r.destination_m)]
        assert min(np.hypot(*(child - np.asarray(p))) for p in stops) > cfg.radius_m  # nothing served on move 1
        after = brute_force_moves(tuple(child), requests, *rules, max_moves=optimum)
        expert = ReplanExpert(cfg, 1, beam=256)
        label = expert.labels(venv, np.array([heading]))[0]
        assert (label == heading) == (after is not None and 1 + after <= optimum), heading
        kept.append(label == heading)
    assert 1 <= sum(kept) < len(kept)  # some headings tie with the best, others are longer


@pytest.mark.parametrize("lookahead", [False, True])
def test_imitate_end_to_end_writes_loadable_checkpoints(tmp_path, lookahead: bool) -> None:
    """One small DAgger round from the shipped stop-head generalist: progress.csv has its rows, best.pt and last.pt
    load with load_policy as heading-residual policies (with ``--lookahead``: observing and reading the look-ahead),
    and an existing run is refused without --overwrite."""
    from uamfleet.config import ConfigError
    from uamfleet.rl.imitation import imitate
    from uamfleet.rl.policy import load_policy

    args = ImitationArgs.from_flat(dict(
        thresholds=(-5.0,), envs_per_threshold=2, rounds=1, steps_per_round=8, eval_instances=2, epochs=1,
        minibatch=16, run_dir=tmp_path, run_name="tiny", lookahead=lookahead,
        train="lookahead" if lookahead else "residual", lookahead_rule=LOOKAHEAD_RULE if lookahead else 0.0,
    ))  # fmt: skip
    best = imitate(args)
    assert best["val_pr_pct"] == 100.0
    rows = (tmp_path / "tiny" / "progress.csv").read_text().splitlines()
    assert rows[0].startswith("round,") and len(rows) == 3  # header, the untrained policy, round 0
    for name in ("best.pt", "last.pt"):
        policy, _ = load_policy(tmp_path / "tiny" / name)
        assert policy.net.cfg.heading_residual
        assert policy.net.cfg.lookahead_inputs == lookahead
        assert policy.net.cfg.lookahead_rule == (LOOKAHEAD_RULE if lookahead else 0.0)
        assert policy.trained_on is not None and policy.trained_on.heading_lookahead == lookahead
    with pytest.raises(ConfigError, match="--overwrite"):
        imitate(args)
    with pytest.raises(ConfigError, match="pass --lookahead"):
        ImitationArgs.from_flat(dict(train="lookahead"))
    with pytest.raises(ConfigError, match=r"--lookahead-rule=100\.0 weighs the look-ahead: pass --lookahead"):
        ImitationArgs.from_flat(dict(lookahead_rule=100.0))
    with pytest.raises(ConfigError, match="--lookahead-rule"):
        ImitationArgs.from_flat(dict(lookahead=True, lookahead_rule=-1.0))


def test_a_lookahead_depth_is_refused_without_the_lookahead_or_outside_one_and_two(tmp_path) -> None:
    """``--lookahead-depth`` without ``--lookahead`` is refused when parsed; a depth other than 1 or 2 by the run's
    EnvConfig, before the run folder is made."""
    from uamfleet.config import ConfigError
    from uamfleet.rl.imitation import imitate

    with pytest.raises(ConfigError, match="--lookahead-depth=2 is the look-ahead's depth: pass --lookahead"):
        ImitationArgs.from_flat(dict(lookahead_depth=2))
    args = ImitationArgs.from_flat(
        dict(lookahead=True, train="lookahead", lookahead_depth=3, run_dir=tmp_path, run_name="deep")
    )
    with pytest.raises(ConfigError, match="lookahead_depth=3 must be 1"):
        imitate(args)
    assert not (tmp_path / "deep").exists()


def _anticipating(cfg, **prior_kw) -> AnticipatingExpert:  # type: ignore[no-untyped-def]
    from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior
    from uamfleet.sim.generator import flyable_sites
    from uamfleet.sim.world import World

    fields = dict(min_requests=2, max_requests=6, window_steps=39, min_trip_m=200.0, sites=flyable_sites(World(cfg)))
    prior = DemandPrior(**{**fields, **prior_kw})  # type: ignore[arg-type]
    planner = AnticipatingReplan(prior, futures=2, scored=2, replan=SearchSettings(32, rank_slack=0.5),
                                 future_beam=8, score_beam=4)  # fmt: skip
    return AnticipatingExpert(cfg, 1, planner, seed=3)


def test_the_anticipating_teacher_replays_replan_where_no_request_can_come() -> None:
    """Both requests released at the start and the prior's most: the teacher's one decision is replan's plan, and
    its labels flown give the distance and steps that plan promised."""
    requests = (Request(0, (380.0, 560.0), (600.0, 330.0)), Request(0, (230.0, 400.0), (470.0, 420.0)))
    cfg = small_config(OPEN_7, starts_m=((110.0, 620.0),), requests=requests, time_limit_steps=40)
    venv = VectorEnv(cfg, 1, autoreset=False)
    venv.reset(seed=0)
    promised = StepSearch(cfg).solve(venv.state, [SearchSettings(beam=32, rank_slack=0.5)])
    assert promised is not None
    expert = _anticipating(cfg, min_requests=1, max_requests=2)
    distance, steps = _flown(venv, expert)  # type: ignore[arg-type]
    assert distance == promised.moves * cfg.step_m and steps == promised.steps
    assert expert.solves == 1


def test_the_anticipating_teacher_never_reads_a_hidden_request_and_redecides_alike() -> None:
    """Two instances that differ only in a request released at step 5 get the same labels until then; and a
    decision taken again in the same state (as after a deviation) draws the same futures: the same plan."""
    first = Request(0, (150.0, 150.0), (550.0, 550.0))
    labelled = []
    for later in (Request(5, (650.0, 50.0), (50.0, 650.0)), Request(5, (350.0, 650.0), (650.0, 250.0))):
        cfg = small_config(OPEN_7, starts_m=((350.0, 350.0),), requests=(first, later), time_limit_steps=60)
        venv = VectorEnv(cfg, 1, autoreset=False)
        venv.reset(seed=0)
        expert = _anticipating(cfg, window_steps=10, max_requests=3)
        labels = []
        for _ in range(5):
            label = expert.labels(venv)
            again = list(expert.plans[0])
            expert.valid[:] = False  # decide again in the same state
            assert expert.labels(venv)[0] == label[0] and expert.plans[0] == again
            labels.append(int(label[0]))
            venv.step(label[:, None])
            expert.advance(label, np.zeros(1, bool), np.zeros(1, bool))
        labelled.append(labels)
    assert labelled[0] == labelled[1]
    assert expert.planner.futures == 2 and expert.solves >= 5  # futures were drawn at every decision


class _WaitingTeacher:
    """Labels a heading the rule forbids (a wait) wherever one exists, else the first allowed heading."""

    solves = corrections = 0
    solve_s = 0.0

    def __init__(self) -> None:
        self.waits = 0

    def labels(self, venv: VectorEnv, proposals: np.ndarray | None = None) -> np.ndarray:
        mask = venv.state.action_mask[:, 0]  # [E, 16]
        forbidden = ~mask.all(axis=1)
        self.waits += int(forbidden.sum())
        return np.where(forbidden, np.argmin(mask, axis=1), np.argmax(mask, axis=1)).astype(np.int64)

    def advance(self, executed: np.ndarray, released: np.ndarray, ended: np.ndarray) -> None:
        pass


def test_collect_flies_the_teachers_waits_but_never_fits_them() -> None:
    """A teacher's plan over a sampled future may wait for a release (a heading the rule forbids leaves the taxi in
    place): collect flies such a label (beta 1) but fits only the labels the action mask allows."""
    cfg = make_config("berlin_instances", sinr_min_db=-3.0, time_limit_steps=200)
    venv = VectorEnv(cfg, num_envs=4)
    obs, _ = venv.reset(seed=1)
    net = MSHAActorCritic(
        venv.single_observation_space,
        NetConfig(variant="de_msfea", d_model=16, num_heads=2, action_head="stops", heading_residual=True,
                  **observed_inputs(venv.single_observation_space.spaces, "de_msfea", "stops")),
    )  # fmt: skip
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    normalizer = ObservationNormalizer(shapes)
    policy = GreedyPolicy(net, normalizer, torch.device("cpu"), shapes, 1, cfg.num_passengers, cfg)
    teacher = _WaitingTeacher()
    data = collect([Group(venv, teacher, obs, np.zeros(4, np.int64))], policy, 1.0, 30, np.random.default_rng(0))  # type: ignore[arg-type]
    assert teacher.waits > 0, "no forbidden heading was labelled: the test would not see the rule"
    assert len(data) == 4 * 30 - teacher.waits
    _, labels, _ = data.arrays()
    assert labels.max() < NUM_HEADINGS


class _LeastPriorTeacher(_WaitingTeacher):
    """Labels the allowed heading the stop head's prior likes least (mostly one it rules out)."""

    def __init__(self, policy: GreedyPolicy) -> None:
        super().__init__()
        self.policy = policy
        self.group: Group | None = None  # whose current observation it reads

    def labels(self, venv: VectorEnv, proposals: np.ndarray | None = None) -> np.ndarray:
        assert self.group is not None
        inputs = obs_to_torch(self.policy.network_input(self.group.obs), "cpu")
        with torch.no_grad():
            prior = self.policy.net.prior_logits(inputs).numpy()
        allowed = venv.state.action_mask[:, 0]
        return np.argmin(np.where(allowed, prior, np.inf), axis=1).astype(np.int64)


def test_skip_ruled_out_fits_only_labels_the_prior_reaches() -> None:
    """With ``skip_ruled_out``, a label whose prior log-probability is at the floor (a heading toward no known stop)
    is flown but not fitted; without it, it is fitted."""
    cfg = make_config("berlin_instances", sinr_min_db=-5.0, time_limit_steps=200)
    sizes = []
    for skip in (False, True):
        venv = VectorEnv(cfg, num_envs=2)
        obs, _ = venv.reset(seed=1)
        torch.manual_seed(0)
        net = MSHAActorCritic(
            venv.single_observation_space,
            NetConfig(variant="de_msfea", d_model=16, num_heads=2, action_head="stops", heading_residual=True,
                      **observed_inputs(venv.single_observation_space.spaces, "de_msfea", "stops")),
        )  # fmt: skip
        shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
        policy = GreedyPolicy(
            net, ObservationNormalizer(shapes), torch.device("cpu"), shapes, 1, cfg.num_passengers, cfg
        )
        teacher = _LeastPriorTeacher(policy)
        group = teacher.group = Group(venv, teacher, obs, np.zeros(2, np.int64))  # type: ignore[arg-type]
        data = collect([group], policy, 1.0, 15, np.random.default_rng(0), skip_ruled_out=skip)
        sizes.append(len(data))
        if skip and len(data):
            x, y, _ = data.arrays()
            with torch.no_grad():
                prior = net.prior_logits(obs_to_torch(x, "cpu")).numpy()
            assert np.all(prior[np.arange(len(y)), y] > PRIOR_FLOOR)
    assert sizes[0] == 2 * 15 and sizes[1] < sizes[0]


def test_imitate_with_the_anticipating_teacher_end_to_end(tmp_path) -> None:
    """One small round with ``--expert futures`` (the family's demand model on each threshold's sites): labels are
    fitted and the checkpoints load; a bad futures setting is refused by name."""
    from uamfleet.config import ConfigError
    from uamfleet.rl.imitation import imitate
    from uamfleet.rl.policy import load_policy

    args = ImitationArgs.from_flat(dict(
        thresholds=(-5.0,), envs_per_threshold=1, rounds=1, steps_per_round=6, eval_instances=1, epochs=1,
        minibatch=4, run_dir=tmp_path, run_name="fut", expert="futures", futures=1, scored_futures=1, expert_beam=8,
        future_beam=4, score_beam=2,
    ))  # fmt: skip
    best = imitate(args)
    assert best["val_pr_pct"] == 100.0
    rows = (tmp_path / "fut" / "progress.csv").read_text().splitlines()
    assert len(rows) == 3 and int(rows[2].split(",")[rows[0].split(",").index("new_samples")]) > 0
    policy, _ = load_policy(tmp_path / "fut" / "best.pt")
    assert policy.net.cfg.heading_residual
    with pytest.raises(ConfigError, match="--scored-futures"):
        ImitationArgs.from_flat(dict(expert="futures", scored_futures=0))
