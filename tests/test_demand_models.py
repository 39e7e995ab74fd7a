"""Demand models (uamfleet/baselines/demand_models.py): the estimated model recovers a known capped stream law from
drawn episodes, every model keeps ``DemandPrior.sample``'s contract, the true law of a family without one samples
as ``DemandPrior``, and a fitted model survives its JSON; ``uamfleet demand fit / check``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from uamfleet.baselines.anticipation import DemandPrior
from uamfleet.baselines.demand_models import EstimatedDemand, FamilyLaw, demand_model, wrong_law, wrong_model
from uamfleet.baselines.step_planner import released_only
from uamfleet.checks import ConfigError
from uamfleet.cli.main import cli
from uamfleet.demand import DemandLaw
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_instance
from uamfleet.presets import make_config
from uamfleet.sim.generator import flyable_sites
from uamfleet.sim.world import World
from uamfleet.types import HIDDEN

SLOT_S = 3.0
# a capped stream: 1 request at step 0, then 1 per minute over 5 minutes (100 steps), at most 5 in all (the cap
# cuts P(Poisson(5) >= 4) = 73 % of the episodes short), origins around two hot spots
LAW = DemandLaw("poisson_stream", 1, 5, window_s=300.0, rate_per_min=1.0,
                hotspots=((800.0, 800.0, 300.0), (2400.0, 2200.0, 400.0)))  # fmt: skip


@pytest.fixture(scope="module")
def sites() -> np.ndarray:
    return flyable_sites(World(make_config("berlin_random", sinr_min_db=-5.0)))


def _episodes(sites: np.ndarray, count: int, seed: int) -> list[list]:
    rng = np.random.default_rng(seed)
    return [LAW.draw(rng, sites, SLOT_S) for _ in range(count)]


def test_the_estimated_model_recovers_a_known_capped_stream_law(sites: np.ndarray) -> None:
    episodes = _episodes(sites, 2000, seed=0)
    model = EstimatedDemand.fit(episodes, SLOT_S, bin_steps=5)
    assert model.cap == 5 and model.window_steps == 105  # one bin past the last release (step 100)
    np.testing.assert_array_equal(model.initial_pmf, [0, 1, 0, 0, 0, 0])
    rate = LAW.rate_per_min * SLOT_S / 60.0  # the law's arrivals per step
    releases = [np.array([r.release_step for r in e]) for e in episodes]
    for b in range(20):
        steps = np.arange(1 + 5 * b, 1 + 5 * (b + 1))
        # at-risk steps: an episode counts at step s while fewer than the cap were released before s
        exposure = sum(int(((r[:, None] < steps).sum(0) < 5).sum()) for r in releases)
        got = model.intensity[steps]
        assert np.all(got == got[0])  # one intensity per bin
        assert abs(got[0] - rate) < 3 * math.sqrt(rate / exposure), (b, got[0], rate, exposure)
    assert model.intensity[0] == 0.0
    # past the service nothing arrives: the extra bin holds half an arrival over its at-risk steps
    late = np.arange(101, 106)
    exposure = sum(int(((r[:, None] < late).sum(0) < 5).sum()) for r in releases)
    np.testing.assert_allclose(model.intensity[101:], 0.5 / exposure)
    truth, _ = LAW.site_pmf(sites)
    tv = 0.5 * np.abs(model.on_world(sites).origin_pmf - truth).sum()
    more = EstimatedDemand.fit(_episodes(sites, 8000, seed=1), SLOT_S).on_world(sites)
    assert tv < 0.10 and 0.5 * np.abs(more.origin_pmf - truth).sum() < tv
    # held out: the fitted model scores the law's episodes near the law itself, far above a wrong law
    held = _episodes(sites, 200, seed=2)
    fitted, true = model.on_world(sites), FamilyLaw(LAW, sites, SLOT_S)
    wrong = FamilyLaw(wrong_law(LAW, sites), sites, SLOT_S)
    ll = np.array([[m.log_likelihood(e, SLOT_S) for m in (fitted, true, wrong)] for e in held])
    assert np.isfinite(ll[:, :2]).all()
    finite = np.isfinite(ll).all(1)
    assert ll[finite, 0].mean() > ll[finite, 2].mean() + 1.0
    assert abs(ll[:, 0].mean() - ll[:, 1].mean()) < 0.02 * abs(ll[:, 1].mean())


def test_the_stream_log_likelihood_by_hand(sites: np.ndarray) -> None:
    law = DemandLaw("poisson_stream", 1, 3, window_s=9.0, rate_per_min=20.0)  # 1 arrival per 3 s step, 3 steps
    true = FamilyLaw(law, sites, SLOT_S)
    a, b, c = (tuple(sites[i]) for i in (0, -1, 1))
    far = np.linalg.norm(sites - sites[0], axis=-1) >= 500.0
    trip = math.log(1 / len(sites)) - math.log(far.sum())  # uniform origin among sites with a far site (all here)
    from uamfleet.demand import Request

    # one at 0, then 0 arrivals at step 1 (P = e^-1), then 2 at step 2: the cap (3) is reached, P(N >= 2)
    requests = [Request(0, a, b), Request(2, a, b), Request(2, a, b)]
    timing = -1.0 + math.log(1 - 2 * math.exp(-1))
    assert c != a
    assert math.isclose(true.log_likelihood(requests, SLOT_S), timing + 3 * trip, rel_tol=1e-9)
    assert true.log_likelihood([*requests, Request(3, a, b)], SLOT_S) == -math.inf  # past the cap
    with pytest.raises(ConfigError, match=r"^slot_s=9.6 s: .* counts steps of 3 s; score episodes of that world\.$"):
        true.log_likelihood(requests, 9.6)


def _states(family: str, seed: int) -> list:
    """Released-only states of an instance at steps 0, 7 and 45 (flying the first unmasked action)."""
    cfg = make_instance(family, seed, max_passengers=6)
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    out = []
    for step in range(46):
        if step in (0, 7, 45):
            out.append(released_only(env.state))
        env.step(np.array([[int(np.argmax(env.state.action_mask[0, 0]))]]))
    return out


@pytest.mark.parametrize("family", ["berlin_stream", "berlin_peak", "berlin_burst"])
def test_every_model_keeps_the_sample_contract(family: str, tmp_path) -> None:
    cfg = make_instance(family, 1_000_001, max_passengers=6)
    fitted_path = tmp_path / "m.json"
    EstimatedDemand.fit([make_instance(family, s).requests for s in range(40)], cfg.slot_s).save(fitted_path)
    models = [demand_model(spec, cfg) for spec in ("family", family, str(fitted_path), "wrong")]
    assert [type(m).__name__ for m in models] == ["FamilyLaw", "FamilyLaw", "EstimatedDemand", "FamilyLaw"]
    rng = np.random.default_rng(3)
    sites = flyable_sites(World(cfg))
    for known in _states(family, 1_000_001):
        t, rows = int(known.t[0]), known.pax_exists[0].copy()
        for model in models:
            drawn = 0
            for _ in range(30):
                future = model.sample(known, rng)
                if future is None:
                    continue
                new = future.pax_exists[0] & ~rows
                drawn += 1
                assert new.any() and future.pax_exists[0].sum() <= model.max_requests
                for name in ("pax_exists", "pax_status", "pax_origin_m", "pax_dest_m", "pax_release", "pax_taxi"):
                    assert np.array_equal(getattr(future, name)[0, rows], getattr(known, name)[0, rows]), name
                assert np.all(future.pax_status[0, new] == HIDDEN)
                assert np.all((future.pax_release[0, new] > t) & (future.pax_release[0, new] <= model.window_steps))
                trips = np.linalg.norm(future.pax_origin_m[0, new] - future.pax_dest_m[0, new], axis=-1)
                min_trip = model.law.min_trip_m if isinstance(model, FamilyLaw) else model.min_trip_m
                assert np.all(trips >= min_trip)
                for point in np.concatenate([future.pax_origin_m[0, new], future.pax_dest_m[0, new]]):
                    assert np.min(np.linalg.norm(sites - point, axis=-1)) == 0.0  # a flyable site of this world
            if t == 0 and rows.sum() < model.max_requests:
                assert drawn > 0, (family, type(model).__name__)  # at the start more usually comes


def test_the_true_law_of_a_family_without_one_samples_as_the_demand_prior() -> None:
    for family, seed in (("berlin", 1_000_003), ("detroit3gpp", 1_000_001)):
        cfg = make_instance(family, seed, max_passengers=6)
        law, prior = FamilyLaw.of_family(family, cfg), DemandPrior.of_family(family, cfg)
        assert (law.max_requests, law.window_steps) == (prior.max_requests, prior.window_steps)
        for known in _states(family, seed)[:2]:
            a, b = np.random.default_rng(5), np.random.default_rng(5)
            for _ in range(20):
                x, y = law.sample(known, a), prior.sample(known, b)
                assert (x is None) == (y is None)
                if x is not None and y is not None:
                    for name in ("pax_exists", "pax_release", "pax_origin_m", "pax_dest_m", "pax_status"):
                        assert np.array_equal(getattr(x, name), getattr(y, name)), name


def test_a_fitted_model_survives_its_json_and_moves_to_another_world(sites: np.ndarray, tmp_path) -> None:
    model = EstimatedDemand.fit(_episodes(sites, 300, seed=4), SLOT_S, bin_steps=4, floor=0.1)
    path = model.save(tmp_path / "model.json")
    again = EstimatedDemand.load(path)
    assert json.loads(path.read_text())["kind"] == "estimated"
    assert again.to_dict() == model.to_dict()
    held = _episodes(sites, 5, seed=5)
    assert [again.on_world(sites).log_likelihood(e, SLOT_S) for e in held] == [
        model.on_world(sites).log_likelihood(e, SLOT_S) for e in held
    ]
    other = flyable_sites(World(make_config("berlin_random", sinr_min_db=-3.0)))
    moved = model.on_world(other)
    assert len(other) != len(sites) and len(moved.origin_pmf) == len(other)
    assert math.isclose(moved.origin_pmf.sum(), 1.0) and math.isclose(moved.dest_pmf.sum(), 1.0)
    assert moved.origin_pmf.min() > 0
    with pytest.raises(ValueError, match=r"bound to no world: call \.on_world\(sites\)"):
        model.sample(None, np.random.default_rng(0))  # type: ignore[arg-type]
    (tmp_path / "bad.json").write_text('{"kind": "law"}')
    with pytest.raises(ConfigError, match=r"^not an estimated demand model of format 1"):
        EstimatedDemand.load(tmp_path / "bad.json")
    with pytest.raises(FileNotFoundError, match=r"missing.json does not exist; write one with `uamfleet demand"):
        EstimatedDemand.load(tmp_path / "missing.json")


def test_demand_model_names_and_the_wrong_law(sites: np.ndarray) -> None:
    cfg = make_instance("berlin_stream", 1_000_000)
    assert demand_model("family", cfg).law == make_instance.__globals__["FAMILIES"]["berlin_stream"].law
    wrong = wrong_model("berlin_stream", cfg)
    assert wrong.law.arrivals == "peak" and wrong.law.window_s == 420.0 and wrong.law.peak_s == 180.0
    # the hot spots mirrored through the centre of the sites (50 ... 3250 m: 1650 m)
    assert wrong.law.hotspots[0] == (2650.0, 2650.0, 300.0)
    window = wrong_law(DemandLaw("uniform_window", 4, 5, initial=2, window_s=90.0), sites)
    assert window.arrivals == "poisson_stream" and math.isclose(window.rate_per_min * 1.5, 2.5)
    with pytest.raises(ConfigError, match=r"^demand model 'oracle' is unknown; use one of"):
        demand_model("oracle", cfg)
    with pytest.raises(ValueError, match=r"'berlin_p4' is none of"):
        demand_model("family", make_config("berlin_p4"))


def test_the_demand_command_fits_writes_once_and_checks(tmp_path, capsys) -> None:
    out = tmp_path / "burst.json"
    argv = ["demand", "fit", "--family", "berlin_burst", "--count", "6", "--out", str(out)]
    assert cli(argv) == 0
    assert "fitted on 6 berlin_burst train episodes" in capsys.readouterr().out
    assert EstimatedDemand.load(out).episodes == 6
    assert cli(argv) == 2  # an existing model is replaced only with --overwrite
    assert "--overwrite" in capsys.readouterr().err
    check = ["demand", "check", "--model", str(out), "--family", "berlin_burst", "--count", "4"]
    assert cli(check) == 0
    printed = capsys.readouterr().out
    assert "| fitted |" in printed and "| true |" in printed and "| wrong |" in printed
    assert cli(["demand", "fitt"]) == 2
    assert capsys.readouterr().err.startswith("uamfleet demand: error: unknown subcommand 'fitt'; use")
