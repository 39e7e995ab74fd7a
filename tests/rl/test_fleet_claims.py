"""A fleet policy that reads the chosen dispatcher's claims (uamfleet/rl/fleet_claims.py): converted, it flies as
the policy it was converted from; the claims are the dispatcher's schedules, checked by hand on a small drawn
scene; and neither they nor the moves read a request before its release."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from uamfleet import policies
from uamfleet.baselines.sequencing import DROPOFF, PICKUP
from uamfleet.checks import ConfigError
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.rl.fleet_claims import (
    CLAIM_SCORE, ClaimsFleetPolicy, dispatch_claims, onward_marks, open_stops, with_claims, with_dispatch_claims,
)  # fmt: skip
from uamfleet.rl.fleet_imitation import TEACHER, FleetImitationArgs, fleet_imitate, fleet_policy, make_teacher
from uamfleet.rollout import fly, observer_of
from uamfleet.types import DISPATCH_CLAIM_FEATURES, ON_BOARD, WAITING


def scene(taxis: int = 3, requests: int = 8, split: str = "train"):
    """A small drawn Berlin fleet scene under the shield with the hover action (as the fleet benchmark flies)."""
    return make_fleet_instance("berlin", split_seeds(split, 1)[0], taxis, requests, separation="shield",
                               hover_action=True)  # fmt: skip


def claims_policy(taxis: int) -> ClaimsFleetPolicy:
    return ClaimsFleetPolicy(with_dispatch_claims(fleet_policy("berlin_fleet", 24)), make_teacher(TEACHER, taxis))


def test_the_converted_policy_gives_the_same_logits_whatever_the_claims_and_flies_as_the_base() -> None:
    cfg = scene()
    base = fleet_policy("berlin_fleet", 24)
    converted = with_dispatch_claims(fleet_policy("berlin_fleet", 24))
    assert converted.net.cfg.dispatch_claim_inputs and not base.net.cfg.dispatch_claim_inputs
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(base))
    obs, _ = env.reset(seed=0)
    base.reset(env.sim)
    converted.reset(env.sim)
    for _ in range(5):
        obs, *_ = env.step(np.full((1, cfg.num_taxis), 3))
    inputs = base.network_input(obs)
    rows = inputs["passengers"].shape[1]
    drawn = np.random.default_rng(0).integers(0, 2, (cfg.num_taxis, rows, len(DISPATCH_CLAIM_FEATURES)))
    assert drawn.any()
    torch.testing.assert_close(converted.logits_of(with_claims(inputs, drawn)), base.logits_of(inputs), rtol=0, atol=0)
    alone, alongside = fly(cfg, base), fly(cfg, policies.make("fleet_claims"))  # berlin_fleet, claims at zero
    assert np.array_equal(alone.positions_m, alongside.positions_m)
    assert all(np.array_equal(a.actions, b.actions) for a, b in zip(alone.events, alongside.events, strict=True))


def hand_scene():
    """An env after reset with the first three released requests and a dispatcher whose schedules are set by hand."""
    cfg = scene(taxis=2, requests=8)
    first = [r for r in cfg.requests if r.release_step == 0]
    later = [dataclasses.replace(r, release_step=0) for r in cfg.requests[len(first) : 3]]
    cfg = cfg.replace(requests=tuple(first + later) + cfg.requests[3:])  # requests 0, 1, 2 released at step 0
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    dispatcher = make_teacher(TEACHER, 2)
    dispatcher.reset(env.sim)
    return env, dispatcher


def test_claims_by_hand_on_a_small_scene() -> None:
    env, dispatcher = hand_scene()
    s = env.sim.state
    assert (s.pax_status[0, :3] == WAITING).all()
    dispatcher.routes = [
        [(1, PICKUP), (0, PICKUP), (1, DROPOFF), (0, DROPOFF)],  # taxi 0: 1 first, then 0
        [(2, PICKUP), (2, DROPOFF)],  # taxi 1: 2
    ]
    rows = np.array([[0, 2, 1, -1], [1, -1, 2, 0]])
    got = dispatch_claims(rows, dispatcher)
    # columns: scheduled_to_me, scheduled_to_other, my_next_stop, my_schedule_rank
    want = np.array([
        [[1, 0, 0, 1 / 2], [0, 1, 0, 0], [1, 0, 1, 1], [0, 0, 0, 0]],
        [[0, 1, 0, 0], [0, 0, 0, 0], [1, 0, 1, 1], [0, 1, 0, 0]],
    ], np.float32)  # fmt: skip
    np.testing.assert_array_equal(got, want)
    # passenger 1 on board taxi 0 (one seat left): its row now stands for the drop-off, second on the schedule
    s.pax_status[0, 1], s.pax_taxi[0, 1] = ON_BOARD, 0
    s.free_seats[0, 0] = env.sim.cfg.seats - 1
    dispatcher.routes[0] = [(0, PICKUP), (1, DROPOFF), (0, DROPOFF)]
    got = dispatch_claims(rows, dispatcher)
    np.testing.assert_array_equal(got[0, 0], [1, 0, 1, 1])  # passenger 0's pick-up: first, the next stop
    np.testing.assert_array_equal(got[0, 2], [1, 0, 0, 1 / 2])  # passenger 1's drop-off: second
    np.testing.assert_array_equal(got[1, 0], [0, 1, 0, 0])  # taxi 1 reads passenger 1 as taxi 0's
    # no free seat: the pick-up is not a stop taxi 0 can act on now, so the drop-off is its next stop
    s.free_seats[0, 0] = 0
    got = dispatch_claims(rows, dispatcher)
    np.testing.assert_array_equal(got[0, :, 2], [0, 0, 1, 0])


def test_neither_claims_nor_moves_read_a_request_before_its_release() -> None:
    cfg = scene(taxis=3, requests=12)
    late = int(np.argmax([r.release_step for r in cfg.requests]))
    release = cfg.requests[late].release_step
    assert release > 10
    other = cfg.requests[0]  # the late request moved to another trip of the map, unknown until its release
    moved = dataclasses.replace(cfg.requests[late], origin_m=other.destination_m, destination_m=other.origin_m)
    changed = cfg.replace(requests=tuple(moved if i == late else r for i, r in enumerate(cfg.requests)))
    seen = []
    for world in (cfg, changed):
        policy = claims_policy(3)
        env = VectorEnv(world, num_envs=1, autoreset=False, observer=observer_of(policy))
        obs, _ = env.reset(seed=0)
        policy.reset(env.sim)
        moves, claims = [], []
        for _ in range(release):
            moves.append(policy.act(obs).copy())
            claims.append(policy.claims())
            assert all(late not in (p for p, _ in route) for route in policy.dispatcher.routes)
            obs, *_ = env.step(moves[-1])
        seen.append((np.stack(moves), np.stack(claims)))
    np.testing.assert_array_equal(seen[0][0], seen[1][0])
    np.testing.assert_array_equal(seen[0][1], seen[1][1])


def test_a_policy_reading_no_claims_or_a_dispatcher_keeping_none_is_refused() -> None:
    with pytest.raises(ConfigError, match="with_dispatch_claims"):
        ClaimsFleetPolicy(fleet_policy("berlin_fleet", 24), make_teacher(TEACHER, 2))
    with pytest.raises(ConfigError, match="keeps none"):
        ClaimsFleetPolicy(with_dispatch_claims(fleet_policy("berlin_fleet", 24)), policies.make("greedy"))


def test_one_round_learns_the_claims_and_flies_by_its_registry_name(tmp_path) -> None:
    args = FleetImitationArgs(rounds=1, mixture=("2x12",), labels="stop", dispatch_claims=True, run_dir=tmp_path,
                              run_name="claims")  # fmt: skip
    fleet_imitate(args)
    saved = torch.load(tmp_path / "claims" / "round0.pt", weights_only=True)
    assert saved["net_config"]["dispatch_claim_inputs"] is True
    weight = saved["model"][CLAIM_SCORE][0]
    assert weight[0] > 0 and weight[1] < 0  # on my schedule up, on another taxi's down: the labels follow them
    policy = policies.make_named(f"fleet_claims:source={tmp_path / 'claims' / 'round0.pt'}")
    cfg = scene(taxis=2, requests=6, split="validation")
    traj = fly(cfg, policy)
    assert traj.terminated


def test_hover_when_idle_keeps_a_taxi_with_an_open_stop_flying() -> None:
    """A network that would hover every taxi at every step (its hover logit forced to the top): with
    ``hover_when_idle`` only the taxis whose dispatcher schedule is empty hover, the others fly their best heading;
    without it every taxi hovers."""
    from uamfleet.rl.hover import with_hover_anytime
    from uamfleet.types import HOVER_ACTION

    cfg = scene(taxis=3, requests=8)
    checked = {True: 0, False: 0}
    for gate in (True, False):
        policy = ClaimsFleetPolicy(
            with_dispatch_claims(with_hover_anytime(fleet_policy("berlin_fleet", 24))), make_teacher(TEACHER, 3),
            hover_when_idle=gate,
        )  # fmt: skip
        net_logits = policy.policy.logits_of

        def hover_first(inputs, net_logits=net_logits):
            logits = net_logits(inputs).clone()
            logits[:, HOVER_ACTION] = logits.max() + 10.0
            return logits

        policy.policy.logits_of = hover_first
        env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
        obs, _ = env.reset(seed=0)
        policy.reset(env.sim)
        for _ in range(120):  # requests are released over the first 200 steps
            actions = policy.act(obs)[0]
            busy = [bool(open_stops(policy.dispatcher, a)) for a in range(3)]
            for a in range(3):
                hovered = actions[a] == HOVER_ACTION
                assert hovered == (not (gate and busy[a])), (gate, a, busy)
                checked[gate] += busy[a]
            obs, _, terminated, truncated, _ = env.step(actions[None])
            if terminated[0] or truncated[0]:
                break
    assert checked[True] > 0 and checked[False] > 0  # taxis with open stops were met, with and without the gate


ONWARD = ("batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,"
          "unassigned_guard_s=600,heading=onward")  # fmt: skip
"""The chosen dispatcher (:data:`TEACHER`) flying ``heading=onward``, in the full form that takes the option."""


def test_onward_marks_are_the_onward_dispatchers_move_where_it_makes_a_stop_and_leave_every_other_row() -> None:
    """Fly the dispatcher with ``heading=onward`` on a small scene: wherever a taxi's move makes the stop it heads
    for and a stop follows it on its schedule, the mark :func:`onward_marks` sets on that stop's row is the move the
    dispatcher flies (the move, judged here by hand, ends within the pick-up radius of the stop, and of such moves
    ends nearest the stop after it); every other row keeps the env's mark. The rule marks another heading than the
    env's table somewhere, so the option changes what the network reads."""
    cfg = scene(taxis=3, requests=10)
    reader = claims_policy(3)
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(reader))
    obs, _ = env.reset(seed=0)
    reader.reset(env.sim)
    dispatcher = make_teacher(ONWARD, 3)
    dispatcher.reset(env.sim)
    radius = env.sim.cfg.radius_m
    marked = differs = 0
    for _ in range(400):
        actions = dispatcher.act(obs)[0]
        claims = dispatch_claims(reader._observer.window_rows(env.sim.state)[0], dispatcher)
        marks = onward_marks(obs["stop_heading_mask"], claims, dispatcher)
        changed = (marks != obs["stop_heading_mask"]).any(-1)[0]  # [A, K]
        for a in range(3):
            target, after = dispatcher.target_and_after(a)
            rows = np.flatnonzero(claims[a, :, 2])  # my next stop
            if target is None or after is None or not rows.size or not obs["stop_heading_mask"][0, a, rows[0]].any():
                assert not changed[a].any()
                continue
            ends = env.sim.state.pos_m[0, a] + env.sim.world.moves_m
            makes = env.sim.state.action_mask[0, a, :16] & (((ends - target) ** 2).sum(-1) <= radius**2)
            if not makes.any():  # the stop is more than a move away: the env's mark stays
                assert not changed[a].any()
                continue
            k = rows[0]
            assert not np.delete(changed[a], k).any()
            assert marks[0, a, k].sum() == 1 and marks[0, a, k, actions[a]] == 1, (a, actions[a])
            assert makes[actions[a]]
            far = dispatcher.fields.remaining_m(after, ends)
            assert far[actions[a]] == far[makes].min()
            marked += 1
            differs += bool(changed[a, k])
        obs, _, terminated, truncated, _ = env.step(actions[None])
        if terminated[0] or truncated[0]:
            break
    assert marked >= 5 and differs >= 1, (marked, differs)


def test_a_claims_policy_with_onward_marks_flies_by_its_registry_name_and_a_bad_heading_is_named() -> None:
    """By name, ``heading=onward`` flies other moves than ``heading=table`` on the same scene (the marks reach the
    network), and an unknown heading is refused, naming it."""
    cfg = scene(taxis=3, requests=10)
    flights = {h: fly(cfg, policies.make_named(f"fleet_claims:heading={h}")) for h in ("table", "onward")}
    assert policies.make_named("fleet_claims:heading=onward").heading == "onward"
    assert flights["onward"].terminated
    assert not np.array_equal(flights["onward"].positions_m, flights["table"].positions_m)
    with pytest.raises(policies.PolicyNameError, match="heading='sideways'"):
        policies.make_named("fleet_claims:heading=sideways")


def test_training_on_onward_marks_labels_the_onward_teachers_moves_and_needs_the_claims() -> None:
    """Labelled at the stop head's level on the teacher's own episode (beta 1: the same flight either way), the
    onward teacher's moves that make a stop become labels the network flies to that stop only when it reads the
    onward marks: with them more labels are the teacher's own moves than with the env's table marks."""
    from uamfleet.rl.fleet_imitation import label_episode

    cfg = scene(taxis=3, requests=10)
    agree = {}
    for heading in ("table", "onward"):
        policy = with_dispatch_claims(fleet_policy("berlin_fleet", 24))
        episode = label_episode(cfg, policy, make_teacher(ONWARD, 3), 1.0, np.random.default_rng(0), "stop",
                                -np.inf, claims_heading=heading)  # fmt: skip
        agree[heading] = int((episode.labels == episode.teacher_actions.reshape(-1)).sum())
    assert agree["onward"] > agree["table"], agree
    with pytest.raises(ConfigError, match="add --dispatch-claims"):
        FleetImitationArgs(claims_heading="onward")


def test_make_way_moves_a_hovering_taxi_out_of_the_path_of_a_taxi_with_a_stop() -> None:
    """A taxi hovers right where another taxi's next move ends (the network's logits are set by hand: the taxi with
    an open stop flies heading ``h``, the other hovers). Without ``make_way`` it keeps hovering (the shield would
    then turn the moving taxi aside); with it, it flies the allowed heading whose end is farthest from that move's
    end (judged here by hand), and the moving taxi keeps its heading."""
    cfg = scene(taxis=2, requests=8)
    first = [r for r in cfg.requests if r.release_step == 0]
    later = [dataclasses.replace(r, release_step=0) for r in cfg.requests[len(first) : 3]]
    cfg = cfg.replace(requests=tuple(first + later) + cfg.requests[3:])  # requests 0, 1, 2 released at step 0
    chosen = {}
    for way in (False, True):
        policy = claims_policy(2)
        policy.make_way = way
        env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
        obs, _ = env.reset(seed=0)
        policy.reset(env.sim)
        policy.dispatcher.act(obs)  # its first assignment: the three requests released at step 0
        busy = next(a for a in range(2) if open_stops(policy.dispatcher, a))
        other = 1 - busy
        s = env.sim.state
        h = int(np.flatnonzero(s.action_mask[0, busy, :16])[0])
        s.pos_m[0, other] = s.pos_m[0, busy] + env.sim.world.moves_m[h]  # hovering where the busy taxi's move ends

        def by_hand(inputs, busy=busy, h=h):
            logits = torch.full((2, 17), -50.0)
            logits[:, 16] = 0.0  # every taxi hovers ...
            logits[busy, 16], logits[busy, h] = -50.0, 0.0  # ... but the one with a stop, which flies h
            return logits

        policy.policy.logits_of = by_hand
        chosen[way] = policy.act(obs)[0]
    assert chosen[False][other] == 16 and chosen[False][busy] == h
    assert chosen[True][busy] == h and chosen[True][other] < 16
    move_end = s.pos_m[0, busy] + env.sim.world.moves_m[h]
    headings = np.flatnonzero(s.action_mask[0, other, :16])
    clearance = np.linalg.norm(s.pos_m[0, other] + env.sim.world.moves_m[headings] - move_end, axis=-1)
    assert chosen[True][other] == headings[int(np.argmax(clearance))]


def test_a_network_trained_on_onward_marks_flies_them_by_default_and_training_reads_what_flight_reads(
    tmp_path,
) -> None:  # fmt: skip
    """One DAgger round on the marks (teacher: the onward dispatcher) records them in the checkpoint, so its registry
    name flies them without ``heading=``. Then the same network, labelled with the policy flying every step (beta 0,
    the onward dispatcher watching), flies exactly the moves it flies by its registry name beside the chosen
    dispatcher: training and flight give the network the same claims and marks."""
    from uamfleet.rl.fleet_imitation import label_episode
    from uamfleet.policies.learned import trained_claims_heading

    args = FleetImitationArgs(rounds=1, mixture=("2x12",), labels="stop", dispatch_claims=True,
                              claims_heading="onward", teacher=ONWARD, run_dir=tmp_path, run_name="marks")  # fmt: skip
    fleet_imitate(args)
    source = tmp_path / "marks" / "round0.pt"
    assert trained_claims_heading(str(source)) == "onward" and trained_claims_heading("berlin_fleet") == "table"
    flown = policies.make_named(f"fleet_claims:source={source}")
    assert flown.heading == "onward"
    cfg = scene(taxis=3, requests=10, split="validation")
    traj = fly(cfg, flown)
    labelled = label_episode(cfg, flown.policy, make_teacher(ONWARD, 3), 0.0, np.random.default_rng(0), "stop",
                             -np.inf, claims_heading="onward")  # fmt: skip
    by_name = np.stack([np.asarray(e.actions).reshape(-1) for e in traj.events])
    np.testing.assert_array_equal(labelled.flown, by_name)
