"""Instance families with a demand law (:class:`uamfleet.demand.DemandLaw`): the drawn requests follow the declared
law (count, release steps, origins), the new families draw their own instances, and the families without a law
draw exactly the instances they drew before laws existed (pinned hashes)."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from scipy import stats

from uamfleet.checks import ConfigError
from uamfleet.demand import DemandLaw
from uamfleet.instances import FAMILIES, make_instance, split_seeds
from uamfleet.presets import make_config
from uamfleet.sim.generator import flyable_sites
from uamfleet.sim.world import World

SLOT_S = 3.0  # Berlin's step
DRAWS = 500
NEW_FAMILIES = ("berlin_stream", "berlin_peak", "berlin_burst")

# sha256 of (threshold, starts, requests) of the first 10 seeds of each split, computed with main's code at e01e277,
# before families had a law: a family with law=None must keep drawing these instances byte for byte
PINNED = {
    ("berlin", "train"): "114950d2be1da0bf1773c560600aa60a233f44d810354eb96b43e448bd7c7fc5",
    ("berlin", "validation"): "7d34d098c8e9ee5180af7521cc8ea46bb65d343c57979765ff435c50618000f5",
    ("berlin", "test"): "3e0bd16a4d5b6a7998ea9e6c2234cd70b8d75204f4ef1bc86c0e632cc6e2a0ab",
    ("detroit3gpp", "train"): "9b1f35409ac22d8fd9946bbfb891665c6d32e5c8efafa47f8e2e8bd8cb8c1e4d",
    ("detroit3gpp", "validation"): "6c39e768a3e8a4cb3a44674649e35eb8daa3e049e5335e84f133a9baab5df52d",
    ("detroit3gpp", "test"): "f29222b16e5ba12f9d7c09974e49a5763d269e6a1b219942b9605ec5abe3dd93",
}


def _instance_hash(family: str, split: str) -> str:
    h = hashlib.sha256()
    for seed in split_seeds(split, 10):
        cfg = make_instance(family, seed)
        requests = [(r.release_step, r.origin_m, r.destination_m) for r in cfg.requests]
        h.update(repr((cfg.sinr_min_db, cfg.starts_m, requests)).encode())
    return h.hexdigest()


@pytest.mark.parametrize("family,split", sorted(PINNED))
def test_families_without_a_law_draw_the_instances_they_always_drew(family: str, split: str) -> None:
    assert FAMILIES[family].law is None
    assert _instance_hash(family, split) == PINNED[family, split]


@pytest.fixture(scope="module")
def sites() -> np.ndarray:
    return flyable_sites(World(make_config("berlin_random", sinr_min_db=-5.0)))


def _draws(law: DemandLaw, sites: np.ndarray, seed: int) -> list[list]:
    rng = np.random.default_rng(seed)
    return [law.draw(rng, sites, SLOT_S) for _ in range(DRAWS)]


def _randomised_pit(steps: np.ndarray, cdf: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """F(s - 1) + V (F(s) - F(s - 1)), V uniform: exactly uniform on [0, 1] when the steps follow ``cdf``, so a KS
    test of discrete steps against their law is exact."""
    below = np.where(steps > 0, cdf[np.maximum(steps - 1, 0)], 0.0)
    return below + rng.uniform(size=len(steps)) * (cdf[steps] - below)


def _chi_square_origins(episodes: list[list], law: DemandLaw, sites: np.ndarray) -> float:
    """p-value of the origins' counts in a 4 x 4 grid of map cells against the law's origin pmf summed per cell."""
    cell = lambda xy: np.minimum((np.asarray(xy) // 825).astype(int), 3) @ (4, 1)  # noqa: E731
    observed = np.bincount([cell(r.origin_m) for e in episodes for r in e], minlength=16)
    pmf, _ = law.site_pmf(sites)
    expected = np.bincount(cell(sites), weights=pmf, minlength=16) * observed.sum()
    keep = expected > 0
    assert observed[~keep].sum() == 0  # no origin where the law puts none
    return float(stats.chisquare(observed[keep], expected[keep]).pvalue)


@pytest.mark.parametrize("family", ["berlin_peak", "berlin_burst"])
def test_a_window_law_draws_its_count_its_release_steps_and_its_origins(family: str, sites: np.ndarray) -> None:
    law = FAMILIES[family].law
    assert law is not None
    episodes = _draws(law, sites, seed=7)
    counts = np.array([len(e) for e in episodes])
    lo, hi = law.min_requests, law.max_requests
    mean, var = (lo + hi) / 2, ((hi - lo + 1) ** 2 - 1) / 12  # the discrete uniform's moments
    assert abs(counts.mean() - mean) < 3 * math.sqrt(var / DRAWS)
    assert counts.min() >= lo and counts.max() <= hi
    # the first `initial` requests are released at step 0; the others are i.i.d. over 0 ... window // slot
    later = np.concatenate([[r.release_step for r in e[law.initial :]] for e in episodes])
    assert all(r.release_step == 0 for e in episodes for r in e[: law.initial])
    if law.arrivals == "peak":  # floor(time / slot) of a normal truncated to [0, window): steps 0 ... 79
        last = math.ceil(law.window_s / SLOT_S) - 1
        a, b = (0 - law.peak_s) / law.peak_sd_s, (law.window_s - law.peak_s) / law.peak_sd_s
        cdf = stats.truncnorm(a, b, loc=law.peak_s, scale=law.peak_sd_s).cdf(np.arange(1, last + 2) * SLOT_S)
    else:  # uniform over 0 ... window // slot
        last = int(law.window_s // SLOT_S)
        cdf = np.arange(1, last + 2) / (last + 1)
    assert later.max() <= last
    pit = _randomised_pit(later, cdf, np.random.default_rng(0))
    assert stats.kstest(pit, "uniform").pvalue > 0.001
    assert _chi_square_origins(episodes, law, sites) > 0.001


def test_the_stream_law_draws_a_capped_poisson_stream_from_its_hot_spots(sites: np.ndarray) -> None:
    law = FAMILIES["berlin_stream"].law
    assert law is not None and law.arrivals == "poisson_stream"
    episodes = _draws(law, sites, seed=11)
    rate = law.rate_per_min / 60.0  # per second
    room = law.max_requests - law.initial

    def capped_mean(seconds: float) -> float:  # E[min(Poisson(rate * seconds), room)]
        k = np.arange(room + 1)
        pmf = stats.poisson(rate * seconds).pmf(k)
        return float((k * pmf).sum() + room * (1 - pmf.sum()))

    assert all(len(e) >= law.initial and all(r.release_step == 0 for r in e[: law.initial]) for e in episodes)
    later = [np.array([r.release_step for r in e[law.initial :]]) for e in episodes]
    assert all(len(x) == 0 or x.min() >= 1 for x in later)  # a stream's arrival after 0 s is released at step >= 1
    last = round(law.window_s / SLOT_S)
    for step in (20, 60, 90, last):  # released by `step` = arrived by step * slot (released at ceil(time / slot))
        by = np.array([(x <= step).sum() for x in later])
        assert abs(by.mean() - capped_mean(step * SLOT_S)) < 3 * by.std() / math.sqrt(DRAWS), step
    assert max(len(e) for e in episodes) == law.max_requests  # the cap is reached (P ≈ 0.29 per episode) ...
    assert all(len(e) <= law.max_requests for e in episodes)  # ... and never passed
    # the first arrival given one arrives: an exponential truncated to the service
    first = np.array([x[0] for x in later if len(x)])
    cdf = (1 - np.exp(-rate * SLOT_S * np.arange(1, last + 1))) / (1 - math.exp(-rate * law.window_s))
    pit = _randomised_pit(first - 1, cdf, np.random.default_rng(1))
    assert stats.kstest(pit, "uniform").pvalue > 0.001
    assert _chi_square_origins(episodes, law, sites) > 0.001
    trips = [np.hypot(*np.subtract(r.origin_m, r.destination_m)) for e in episodes for r in e]
    assert min(trips) >= law.min_trip_m


def test_site_pmf_is_the_hot_spot_mixture_with_a_floor_and_uniform_far_destinations() -> None:
    # sites on a line; 500 m trips: each site's far sites are the two at the other end
    sites = np.array([[0.0, 0.0], [100.0, 0.0], [1000.0, 0.0], [1100.0, 0.0]])
    law = DemandLaw("uniform_window", 2, 3, hotspots=((0.0, 0.0, 100.0),), hotspot_floor=0.2, min_trip_m=500.0)
    bumps = np.exp(-0.5 * np.array([0.0, 1.0, 100.0, 121.0]))
    origin = 0.2 / 4 + 0.8 * bumps / bumps.sum()
    dest = np.array([origin[2:].sum(), origin[2:].sum(), origin[:2].sum(), origin[:2].sum()]) / 2
    got_origin, got_dest = law.site_pmf(sites)
    np.testing.assert_allclose(got_origin, origin, rtol=1e-12)
    np.testing.assert_allclose(got_dest, dest, rtol=1e-12)
    # a site with no other site far enough is never an origin
    lonely = np.vstack([sites, [[550.0, 0.0]]])
    assert DemandLaw("uniform_window", 2, 3, min_trip_m=600.0).site_pmf(lonely)[0][4] == 0.0


def test_a_law_refuses_what_it_cannot_draw_in_one_line() -> None:
    with pytest.raises(ConfigError, match=r"^DemandLaw.arrivals='burst' is unknown; use one of"):
        DemandLaw("burst", 2, 3)
    with pytest.raises(ConfigError, match=r"^DemandLaw.initial=3 .*\(requests at step 0, at most min_requests\)"):
        DemandLaw("uniform_window", 2, 3, initial=3)
    with pytest.raises(ConfigError, match=r"^DemandLaw.min_requests=2 with a poisson_stream .* set min_requests"):
        DemandLaw("poisson_stream", 2, 6, initial=1, rate_per_min=1.0)
    with pytest.raises(ConfigError, match=r"^DemandLaw peak_s=300, peak_sd_s=30: .*inside the window"):
        DemandLaw("peak", 2, 3, window_s=240.0, peak_s=300.0, peak_sd_s=30.0)
    with pytest.raises(ConfigError, match=r"^DemandLaw.hotspots\[0\]=\(1.0, 2.0\) must be \(x_m, y_m, sd_m\)\.$"):
        DemandLaw("uniform_window", 2, 3, hotspots=((1.0, 2.0),))  # type: ignore[arg-type]


@pytest.mark.parametrize("family", NEW_FAMILIES)
def test_a_new_family_draws_its_own_valid_instances_on_every_split(family: str) -> None:
    fam = FAMILIES[family]
    law = fam.law
    assert law is not None and fam.scenario == "berlin_random"
    for split in ("train", "validation", "test"):
        for seed in split_seeds(split, 3):
            cfg = make_instance(family, seed)
            releases = [r.release_step for r in cfg.requests]
            assert law.min_requests <= len(releases) <= law.max_requests
            assert releases == sorted(releases) and releases[: law.initial] == [0] * law.initial
            assert releases[-1] <= fam.window_steps(cfg.slot_s) == law.window_steps(cfg.slot_s)
            assert cfg.sinr_min_db in fam.thresholds_db and cfg.scenario == f"{family}_seed{seed}"
            ours = [(r.release_step, r.origin_m, r.destination_m) for r in cfg.requests]
            berlin = make_instance("berlin", seed)
            assert ours != [(r.release_step, r.origin_m, r.destination_m) for r in berlin.requests]
            assert make_instance(family, seed).requests == cfg.requests  # a function of the seed
