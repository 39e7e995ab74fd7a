"""Fleet dispatchers (insertion, batch_assignment) on small drawn scenes: hand-checked assignments, schedules that
keep capacity and precedence, and the milp trip assignment against brute-force enumeration."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import small_config

from uamfleet.baselines import POLICIES
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy, InsertionPolicy, assign_trips
from uamfleet.baselines.fleet_dispatch import SCHEDULE_DISPATCHERS, DispatchOptions, split_options
from uamfleet.baselines.fleet_steering import fleet_action
from uamfleet.config import Request
from uamfleet.env.protocol import PolicyBase
from uamfleet.env.vector_env import VectorEnv
from uamfleet.policies import make_flown
from uamfleet.presets import make_config
from uamfleet.rollout import run_episode
from uamfleet.types import DELIVERED, WAITING

OPEN_10 = "\n".join(["." * 10] * 10)
WALLED_10 = "\n".join([".........."] * 4 + ["#######..."] + [".........."] * 5)  # a wall with a gap in the east


def _env(**overrides):
    cfg = small_config(OPEN_10, time_limit_steps=200, **overrides)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    return env


def _first_decision(policy, env):
    policy.reset(env.sim)
    policy(None)
    return policy.routes


@pytest.mark.parametrize("cls", [InsertionPolicy, BatchAssignmentPolicy])
def test_two_taxis_each_next_to_one_request_each_take_their_own(cls):
    env = _env(
        starts_m=((150.0, 150.0), (850.0, 850.0)),
        requests=(Request(0, (850.0, 550.0), (350.0, 550.0)), Request(0, (450.0, 150.0), (450.0, 650.0))),
    )
    routes = _first_decision(cls(), env)
    assert routes[0] == [(1, "pickup"), (1, "dropoff")]
    assert routes[1] == [(0, "pickup"), (0, "dropoff")]


@pytest.mark.parametrize("cls", [InsertionPolicy, BatchAssignmentPolicy])
@pytest.mark.parametrize("seats", [1, 2])
def test_two_requests_at_one_place_share_a_taxi_only_when_it_has_the_seats(cls, seats):
    # Taxi 0 is 300 m from the shared origin, taxi 1 about 806 m; the ride is 700 m. Total ride distance:
    # both in taxi 0 with 2 seats 1000 + 1000 = 2000 m < split 1000 + 1506 = 2506 m; with 1 seat taxi 0 would need
    # 1000 + 2400 = 3400 m, so the requests split.
    env = _env(
        seats=seats,
        starts_m=((150.0, 150.0), (850.0, 850.0)),
        requests=(Request(0, (450.0, 150.0), (450.0, 850.0)), Request(0, (450.0, 150.0), (450.0, 850.0))),
    )
    routes = _first_decision(cls(), env)
    if seats == 2:
        assert sorted(routes[0]) == [(0, "dropoff"), (0, "pickup"), (1, "dropoff"), (1, "pickup")]
        assert routes[1] == []
    else:
        assert len(routes[0]) == len(routes[1]) == 2
        assert {routes[0][0][0], routes[1][0][0]} == {0, 1}


class _Checked:
    """A dispatcher whose schedules are checked before every move."""

    def __init__(self, inner):
        self.inner = inner
        self.steps = 0

    def reset(self, sim):
        self.inner.reset(sim)

    def __call__(self, obs):
        actions = self.inner(obs)
        self.inner.check_schedules()
        self.steps += 1
        return actions


def _walled_scene(seats: int):
    """Two taxis, four requests (two at step 0, then steps 4 and 9) on a map walled across but for a gap."""
    return small_config(
        WALLED_10,
        seats=seats,
        time_limit_steps=200,
        starts_m=((150.0, 150.0), (150.0, 850.0)),
        requests=(
            Request(0, (350.0, 250.0), (250.0, 850.0)),
            Request(0, (450.0, 150.0), (150.0, 750.0)),
            Request(4, (750.0, 850.0), (850.0, 150.0)),
            Request(9, (550.0, 650.0), (350.0, 150.0)),
        ),
    )


@pytest.mark.parametrize(
    "name", [*SCHEDULE_DISPATCHERS, "insertion_heuristic", "insertion:heading=table", "batch_assignment:heading=onward"]
)
@pytest.mark.parametrize("seats", [1, 2])
def test_dispatchers_deliver_everyone_and_keep_capacity_and_precedence(name, seats):
    cfg = _walled_scene(seats)
    # insertion with exact_limit=1: every schedule beyond one passenger is repaired by cheapest insertion
    inner = InsertionPolicy(exact_limit=1) if name == "insertion_heuristic" else make_flown(name, num_taxis=2)
    policy = _Checked(inner)
    traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), policy, seed=0)
    assert traj.terminated and not traj.truncated  # everyone delivered
    on_board = np.cumsum(traj.stacked("pickups") - traj.stacked("dropoffs"), axis=0)
    assert on_board.max() <= seats
    picked = traj.stacked("picked_up").argmax(0)
    dropped = traj.stacked("dropped_off").argmax(0)
    assert (picked < dropped).all()
    assert policy.inner.stats["dp_solves"] > 0
    if name == "insertion_heuristic":
        assert policy.inner.stats["heuristic_inserts"] > 0


def test_stop_matrix_is_the_feasible_path_distance_at_every_step():
    """The dispatcher looks its distances up once a decision (taxi to stop) or once an episode (stop to stop); at
    every step of an episode on a walled map each entry equals the field look-up of that pair alone, so no stale
    position or column is ever read."""
    cfg = _walled_scene(seats=2)
    policy = BatchAssignmentPolicy()
    checked = 0

    class _Probe(_Checked):
        def __call__(self, obs):
            nonlocal checked
            actions = super().__call__(obs)
            s = env.state
            active = [int(p) for p in np.flatnonzero((s.pax_status[0] == 1) | (s.pax_status[0] == 2))]
            for taxi in range(env.num_taxis):
                for passengers in (active, active[::-1], active[:1]):
                    if not passengers:
                        continue
                    points = [pt for p in passengers for pt in (policy.origin_m[p], policy.dest_m[p])]
                    got = policy.stop_matrix(taxi, passengers)
                    for j, goal in enumerate(points):
                        alone = policy.fields.remaining_m(goal, np.array([s.pos_m[0, taxi], *points]))
                        alone[1 + j] = 0.0
                        np.testing.assert_array_equal(got[:, 1 + j], alone)
                    checked += 1
            return actions

    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    traj = run_episode(env, _Probe(policy), seed=0)
    assert traj.terminated and checked > 20


def test_stop_distances_are_held_only_for_open_requests():
    """The stop-to-stop distances a dispatcher keeps follow the open requests, not the episode's (a [2P, 2P] matrix
    was 32 MB at 1,000 requests): at every decision it holds columns only of passengers not yet delivered, and
    the passengers it held columns for include ones delivered since, whose columns are gone."""
    cfg = _walled_scene(seats=1)
    policy = BatchAssignmentPolicy()
    held: list[set[int]] = []

    class _Probe(_Checked):
        def __call__(self, obs):
            actions = super().__call__(obs)
            status = env.state.pax_status[0]
            passengers = {j // 2 for j in policy._to_stop}  # the columns held after this decision
            assert all(status[p] != DELIVERED for p in passengers), (env.state.t[0], passengers)
            held.append(passengers)
            return actions

    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    traj = run_episode(env, _Probe(policy), seed=0)
    assert traj.terminated
    ever = set().union(*held)
    assert ever == {0, 1, 2, 3}  # every request's stops were asked for once it was open
    assert len(held[-1]) < len(ever)  # and those delivered by the last decision were dropped


def _brute_force(trips, num_taxis, penalty):
    by_taxi = [[k for k, t in enumerate(trips) if t[0] == a] for a in range(num_taxis)]
    best = (np.inf, None)
    for choice in itertools.product(*[[None, *ks] for ks in by_taxi]):
        chosen = [k for k in choice if k is not None]
        served = [r for k in chosen for r in trips[k][1]]
        if len(served) != len(set(served)):
            continue
        price = penalty if isinstance(penalty, dict) else dict.fromkeys(served, penalty)
        value = sum(trips[k][2] for k in chosen) - sum(price[r] for r in served)
        if value < best[0]:
            best = (value, sorted(chosen))
    return best


def test_milp_assignment_equals_brute_force_enumeration():
    rng = np.random.default_rng(13)
    for _ in range(20):
        num_taxis, requests = 3, [2, 5, 7, 8]
        trips = []
        for a in range(num_taxis):
            for size in (1, 2):
                for combo in itertools.combinations(requests, size):
                    if rng.random() < 0.7:
                        trips.append((a, combo, float(rng.uniform(0, 100) * size)))
        penalty = float(rng.choice([30.0, 1e6]))  # small: leaving a request out can be cheapest
        chosen = assign_trips(trips, num_taxis, requests, penalty)
        value, expected = _brute_force(trips, num_taxis, penalty)
        assert sorted(chosen) == expected
        assert sum(trips[k][2] for k in chosen) - penalty * sum(len(trips[k][1]) for k in chosen) == pytest.approx(
            value
        )


def test_milp_assignment_with_a_price_per_request_equals_brute_force_enumeration():
    rng = np.random.default_rng(17)
    for _ in range(20):
        num_taxis, requests = 3, [2, 5, 7, 8]
        trips = [
            (a, combo, float(rng.uniform(0, 100) * size))
            for a in range(num_taxis)
            for size in (1, 2)
            for combo in itertools.combinations(requests, size)
            if rng.random() < 0.7
        ]
        prices = [float(p) for p in rng.uniform(0, 150, size=len(requests))]  # some below a trip's cost
        chosen = assign_trips(trips, num_taxis, requests, prices)
        _, expected = _brute_force(trips, num_taxis, dict(zip(requests, prices, strict=True)))
        assert sorted(chosen) == expected


def test_a_price_per_unassigned_request_adds_the_wait_so_far():
    """``+price=<s>``: a request left out costs the price plus (1 + β) times its wait so far (worked by hand)."""
    env = _env(
        starts_m=((150.0, 150.0), (850.0, 850.0)),
        requests=(Request(0, (850.0, 550.0), (350.0, 550.0)), Request(2, (450.0, 150.0), (450.0, 650.0))),
    )
    policy = make_flown("batch_assignment+wait=2+price=500", num_taxis=2)
    assert policy.unassigned_price_s == 500.0
    policy.reset(env.sim)
    for _ in range(4):  # to step 4: the requests have waited 12 s and 6 s (3 s steps)
        env.step(policy(None))
    assert policy.unassigned_prices([0, 1]) == [500.0 + 3 * 12.0, 500.0 + 3 * 6.0]
    assert make_flown("batch_assignment", num_taxis=2).unassigned_prices([0, 1]) == 1e6
    guarded = make_flown("batch_assignment+wait=2+price=500+guard=10", num_taxis=2)
    guarded.reset(env.sim)  # the same clock (step 4): request 0 has waited 12 s > 10 s, request 1 6 s
    assert guarded.unassigned_prices([0, 1]) == [1e6, 500.0 + 3 * 6.0]


def test_a_price_can_starve_a_request_and_the_guard_serves_it():
    """Price 0 and β = 0: leaving the request out costs its wait so far, serving it that wait plus the rest of its
    trip, so every batch leaves it out and the taxi never turns to it. Past a guard of 30 s its price is 10^6 s
    again: it is taken, and delivered."""
    requests = (Request(0, (850.0, 850.0), (150.0, 850.0)),)
    delivered = {}
    for name in ("batch_assignment+price=0", "batch_assignment+price=0+guard=30"):
        env = _env(starts_m=((150.0, 150.0),), requests=requests)
        policy = make_flown(name, num_taxis=1)
        policy.reset(env.sim)
        for _ in range(60):
            if env.step(policy(None))[2][0]:  # everyone delivered: the episode is over
                break
        delivered[name] = int(env.state.pax_status[0, 0]) == DELIVERED
        assert policy.stats["assignments"] > 0
    assert delivered == {"batch_assignment+price=0": False, "batch_assignment+price=0+guard=30": True}


def test_dispatchers_are_registered_and_validate_their_settings():
    assert set(SCHEDULE_DISPATCHERS) <= set(POLICIES)
    assert isinstance(make_flown("insertion", num_taxis=4), InsertionPolicy)
    assert isinstance(make_flown("batch_assignment", num_taxis=4), BatchAssignmentPolicy)
    with pytest.raises(ValueError, match="period"):
        BatchAssignmentPolicy(period=0)
    with pytest.raises(ValueError, match="exact_limit"):
        InsertionPolicy(exact_limit=9)


@pytest.mark.parametrize("exact_limit", [1, 6])
@pytest.mark.parametrize("planned_by", [0, 1])
def test_a_taxi_that_boards_passengers_early_or_unplanned_drops_them_before_its_planned_pick_ups(
    exact_limit, planned_by
):
    env = _env(
        starts_m=((150.0, 150.0), (850.0, 850.0)),
        requests=(
            Request(0, (200.0, 150.0), (200.0, 850.0)),
            Request(0, (200.0, 150.0), (250.0, 850.0)),
            Request(0, (750.0, 150.0), (750.0, 850.0)),
        ),
    )
    policy = InsertionPolicy(exact_limit=exact_limit)
    policy.reset(env.sim)
    policy._seen[:] = True  # nothing left to dispatch: the schedules below are the plan
    both = [(0, "pickup"), (0, "dropoff"), (1, "pickup"), (1, "dropoff")]
    policy.routes = (
        [[(2, "pickup"), (2, "dropoff")], both] if planned_by == 1 else [[(2, "pickup"), (2, "dropoff"), *both], []]
    )
    env.step(np.array([[0, 8]]))  # taxi 0 flies east past passengers 0 and 1 and boards both (unplanned or early)
    assert env.state.free_seats[0, 0] == 0
    policy(None)
    policy.check_schedules()
    assert policy.routes[1] == []
    assert sorted(policy.routes[0][:2]) == [(0, "dropoff"), (1, "dropoff")]  # both seats freed before pick-up 2
    policy.schedule_cost(0, policy.routes[0])  # a feasible route: no capacity error


def test_options_in_a_dispatcher_name() -> None:
    assert split_options("batch_assignment") == ("batch_assignment", DispatchOptions())
    assert split_options("batch_assignment_value:100+wait=1.5") == ("batch_assignment_value:100", DispatchOptions(1.5))
    assert split_options("batch_assignment+release+wait=2") == ("batch_assignment", DispatchOptions(2.0, True))
    assert split_options("batch_assignment+price=800") == ("batch_assignment", DispatchOptions(0.0, False, 800.0))
    guarded = split_options("batch_assignment+price=800+guard=600")
    assert guarded == ("batch_assignment", DispatchOptions(0.0, False, 800.0, 600.0))
    assert make_flown("insertion+wait=2", num_taxis=2).wait_weight == 2.0
    policy = make_flown("batch_assignment_value:100+wait=1+release", num_taxis=2)
    assert (policy.wait_weight, policy.assign_on_release, policy.value.price_s) == (1.0, True, 100.0)
    plain = make_flown("batch_assignment", num_taxis=2)
    assert (plain.wait_weight, plain.assign_on_release, plain.value) == (0.0, False, None)
    bad = ["batch_assignment+wait=-1", "insertion+wait=x", "greedy+wait=1", "cptsp+wait=1", "insertion+release",
           "batch_assignment+fast", "batch_assignment+wait", "insertion+price=100", "batch_assignment+price=-1",
           "batch_assignment+price=inf", "batch_assignment+guard=600", "batch_assignment+price=9+guard=-1",
           "insertion+price=9+guard=9"]  # fmt: skip
    for name in bad:
        with pytest.raises(ValueError, match=r"\+|option"):
            make_flown(name, num_taxis=2)


@pytest.mark.parametrize("cls", [InsertionPolicy, BatchAssignmentPolicy])
def test_a_wait_weight_pools_where_ride_time_alone_does_not(cls):
    # One taxi on a line of cell centres (x = 50 + 100 c m): start c = 0; P0 from c = 4 to 2; P1 from 5 to 9; both
    # requested at 0; at 100 m per 3 s slot, in units of 3 s: P0 first rides 6 + 13 = 19 and waits 4 + 9 = 13;
    # pooled (P0, P1 picked up, P0 dropped first) rides 8 + 15 = 23 and waits 4 + 5 = 9. Every other order is
    # worse on both counts than one of these. Plain ride time: P0 first; with β = 2: 19 + 26 = 45 against
    # 23 + 18 = 41 (the next best 43): the pool.
    def at(c: int) -> tuple[float, float]:
        return (50.0 + 100.0 * c, 450.0)

    env = _env(starts_m=(at(0),), requests=(Request(0, at(4), at(2)), Request(0, at(5), at(9))))
    plain = _first_decision(cls(), env)[0]
    assert plain == [(0, "pickup"), (0, "dropoff"), (1, "pickup"), (1, "dropoff")]
    weighted = _first_decision(cls(wait_weight=2.0), _env(starts_m=(at(0),), requests=env.cfg.requests))[0]
    assert weighted == [(0, "pickup"), (1, "pickup"), (0, "dropoff"), (1, "dropoff")]


@pytest.mark.parametrize("on_release", [False, True])
def test_release_triggers_a_batch_assignment(on_release):
    env = _env(starts_m=((150.0, 150.0), (850.0, 850.0)), requests=(Request(1, (450.0, 150.0), (450.0, 650.0)),))
    policy = BatchAssignmentPolicy(period=3, assign_on_release=on_release)
    policy.reset(env.sim)
    routed_at = None
    for _ in range(4):
        t = int(env.state.t[0])
        actions = policy(None)
        if routed_at is None and any(policy.routes):
            routed_at = t
        env.step(actions)
    # released at step 1: assigned then with +release, else at the next multiple of the period, step 3
    assert routed_at == (1 if on_release else 3)


def test_the_fleet_benchmark_checks_dispatcher_names_at_the_fleet_sizes_it_flies():
    from uamfleet.cli.fleet_benchmark import Args, _check_names

    _check_names(Args(settings=("1x6",), dispatchers=("replan", "batch_assignment+wait=1+release")))  # one taxi
    with pytest.raises(ValueError, match="single-taxi planner"):
        _check_names(Args(settings=("4x24",), dispatchers=("replan",)))
    with pytest.raises(ValueError, match="unknown option 'fast'"):
        _check_names(Args(settings=("1x6",), dispatchers=("insertion+fast",)))


@pytest.mark.parametrize(
    ("name", "message"),
    [
        (
            "batch_assignment+price=1+price=2",
            r"'batch_assignment\+price=1\+price=2': \+price=1 and \+price=2 both set "
            r"price; give each option once",
        ),
        ("batch_assignment+release+wait=1+release", r"\+release and \+release both set release"),
        ("insertion+wait=1+wait=1", r"\+wait=1 and \+wait=1 both set wait"),
        ("batch_assignment+price=9+guard=1+guard=2", r"\+guard=1 and \+guard=2 both set guard"),
        ("batch_assignment+wait=1e300", r"\+wait=<…> takes a finite number in \[0, 1000\]"),
        ("batch_assignment+price=1e300", r"\+price=<…> takes a finite number in \[0, 1e\+09\]"),
        ("batch_assignment+price=9+guard=1e12", r"\+guard=<…> takes a finite number in \[0, 1e\+09\]"),
        ("batch_assignment_value:1e300", r"value_price_s=1e\+300 is too large: at most 1e\+09"),
    ],
)
def test_a_dispatcher_name_with_an_option_repeated_or_out_of_range_is_refused(name, message):
    from uamfleet.checks import ConfigError

    with pytest.raises(ConfigError, match=message) as err:
        make_flown(name, num_taxis=2)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("cls", "option", "value", "message"),
    [
        (InsertionPolicy, "exact_limit", 2.5, r"^exact_limit=2\.5 must be a whole number in \[1, 8\]"),
        (InsertionPolicy, "wait_weight", float("inf"), r"^wait_weight=inf must be a finite number"),
        (InsertionPolicy, "wait_weight", 1e6, r"^wait_weight=1000000\.0 is too large: at most 1000 "),
        (BatchAssignmentPolicy, "wait_weight", "1", r"^wait_weight='1' is a str, not a number"),
        (BatchAssignmentPolicy, "period", 1.5, r"^period=1\.5 must be a whole number in \[1, 16777215\]"),
        (BatchAssignmentPolicy, "period", 2**40, r"^period=1099511627776 is too large: at most 16777215 "),
        (
            BatchAssignmentPolicy,
            "max_requests_per_taxi",
            10**4,
            r"^max_requests_per_taxi=10000 is too large: at "
            "most 32 ",
        ),
        (BatchAssignmentPolicy, "max_requests_per_taxi", 0, r"^max_requests_per_taxi=0 must be an integer in "),
        (BatchAssignmentPolicy, "penalty_s", float("nan"), r"^penalty_s=nan must be a finite number"),
        (BatchAssignmentPolicy, "penalty_s", 0.0, r"^penalty_s=0 must be > 0"),
        (BatchAssignmentPolicy, "penalty_s", 1e300, r"^penalty_s=1e\+300 is too large: at most 1e\+09 s"),
        (BatchAssignmentPolicy, "unassigned_price_s", 1e300, r"^unassigned_price_s=1e\+300 is too large"),
        (BatchAssignmentPolicy, "unassigned_price_s", True, r"^unassigned_price_s=True is a bool, not a number"),
        (BatchAssignmentPolicy, "assign_on_release", "yes", r"^assign_on_release='yes' must be True or False"),
        (
            BatchAssignmentPolicy,
            "unassigned_guard_s",
            600.0,
            r"^unassigned_guard_s=600\.0 bounds the wait "
            r"unassigned_price_s prices, which is None: give both",
        ),
        (BatchAssignmentPolicy, "value", "shipped", r"^value='shipped' is a str; pass a LinearValue or None"),
    ],
)
def test_the_dispatchers_check_each_option_in_the_api(cls, option, value, message):
    from uamfleet.checks import ConfigError

    with pytest.raises(ConfigError, match=message):
        cls(**{option: value})


def test_make_flown_checks_its_numbers():
    from uamfleet.checks import ConfigError

    with pytest.raises(ConfigError, match=r"^num_taxis=0 must be an integer in \[1, 1024\]"):
        make_flown("batch_assignment", num_taxis=0)
    with pytest.raises(ConfigError, match=r"^seed=-1 must be an integer"):
        make_flown("random", seed=-1)
    with pytest.raises(ConfigError, match=r"^arrival_window_s=0 must be a positive number"):
        make_flown("batch_assignment_value", num_taxis=2, arrival_window_s=0)
    with pytest.raises(ConfigError, match=r"^--policy None is a NoneType; name a policy"):
        make_flown(None)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--dispatchers", "insertion", "batch_assignment", "insertion"],
            "--dispatchers names insertion more than once; name each dispatcher once.",
        ),
        (
            ["--dispatchers", "batch_assignment+price=1+price=2"],
            "dispatcher 'batch_assignment+price=1+price=2': "
            "+price=1 and +price=2 both set price; give each option once",
        ),
    ],
)
def test_the_fleet_benchmark_refuses_repeated_dispatchers_and_options_in_one_line(argv, message, capsys, tmp_path):
    from uamfleet.cli import fleet_benchmark

    try:
        status = fleet_benchmark.cli([*argv, "--settings", "2x12", "--count", "1", "--out-csv",
                                      str(tmp_path / "out.csv")])  # fmt: skip
    except SystemExit as done:
        status = int(done.code or 0)
    err = capsys.readouterr().err
    assert status == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("cls", [InsertionPolicy, BatchAssignmentPolicy])
def test_heading_table_flies_the_move_the_observation_marks_for_the_stop(cls) -> None:
    """``heading="table"``: every taxi with a stop flies the heading the env's own ``stop_heading_mask`` marks for
    that stop's row (the observation's kernel, read from the observation, not the dispatcher's call), where the
    default field rule flies another heading at some steps; everyone is still delivered."""
    cfg = make_config("berlin_random", num_taxis=3, stop_features=True, sinr_min_db=-5.0)
    checked = {"table": 0, "field differs": 0}

    class Compared(PolicyBase):
        def __init__(self) -> None:
            self.inner = cls(heading="table")

        def reset(self, sim) -> None:
            self.inner.reset(sim)

        def act(self, obs):
            moves = self.inner.act(obs)[0]
            for a, k in enumerate(moves):
                stop = self.inner.next_stop(a)
                if stop is None:
                    continue
                marked = obs["stop_heading_mask"][0, a, stop[0]]
                assert marked.any() and k == int(marked.argmax()), (a, stop, k)
                checked["table"] += 1
                target = self.inner.target(a)
                by_field = fleet_action(self.inner.sim, self.inner.fields, [None] * len(moves), a, target)
                checked["field differs"] += int(by_field != k)
            return moves[None]

    traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), Compared(), seed=3)
    assert traj.terminated  # everyone delivered
    assert checked["table"] > 50 and checked["field differs"] > 0, checked


@pytest.mark.parametrize("cls", [InsertionPolicy, BatchAssignmentPolicy])
def test_heading_onward_makes_the_stop_with_the_move_nearest_the_next_one(cls) -> None:
    """``heading="onward"``, by hand on an open 1 km map (100 m moves, pick-up radius 100 m, headings 22.5° apart
    counter-clockwise from east). The taxi at (400, 500), the rider's origin 80 m east at (480, 500), the
    destination at (480, 100), south. Moves ending within 100 m of the origin: heading 14 (470.7, 429.3) 71 m
    away, 15 (492.4, 461.7) 40 m, 0 (500, 500) 20 m, 1 40 m, 2 (470.7, 570.7) 71 m; heading 3 ends 101 m away.
    Onward flies heading 14, whose end is nearest the destination (329 m; 362, 400, 438 and 471 for the others),
    and the rider boards on that move. The field rule flies heading 2: the field reads the origin's 100 m raster
    cell, whose centre (450, 550) that end is nearest, so it does not fly the end nearest the stop either."""
    env = _env(starts_m=((400.0, 500.0),), requests=(Request(0, (480.0, 500.0), (480.0, 100.0)),))
    assert env.cfg.radius_m == env.cfg.step_m == 100.0 and env.world.radio.resolution_m == 100.0
    field, onward = cls(), cls(heading="onward")
    for policy in (field, onward):
        policy.reset(env.sim)
    assert int(field.act(None)[0, 0]) == 2 and int(onward.act(None)[0, 0]) == 14
    assert np.allclose(onward.stop_after(0), (480.0, 100.0))
    env.step(np.array([[14]]))
    assert env.state.pax_status[0, 0] != WAITING  # boarded on the onward move
    assert onward.stop_after(0) is None  # the drop-off is its last stop: the field rule flies on
    assert int(onward.act(None)[0, 0]) == int(field.act(None)[0, 0])
