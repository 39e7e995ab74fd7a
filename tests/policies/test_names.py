"""The policy grammar: every name recorded in the committed CSVs reads as its call, parse and format are inverse, and
bad names are refused in one line that names what exists."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import pytest

import uamfleet
from uamfleet import policies
from uamfleet.policies import PolicyNameError, format, parse

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = Path(uamfleet.__file__).parent / "data" / "pretrained"
L: tuple[str, dict] = ("learned", {})
V = "batch_assignment_value"
W1R = {"wait": 1.0, "release": True}

# Every distinct method / dispatcher of docs/results/**/*.csv, listed by hand with the call it stands for.
RECORDED: dict[str, tuple[str, dict]] = {
    "best_known": ("best_known", {}),
    "cptsp": ("cptsp", {}),
    "pdpcc": ("pdpcc", {}),
    "raster_opt": ("raster_opt", {}),
    "raster_replan": ("raster_replan", {}),
    "replan": ("replan", {}),
    "replan_futures": ("replan_futures", {}),
    "straight": ("straight", {}),
    "learned": L,
    "msha-de_msfea": L,
    "learned_finish": ("finish", {"base": L}),
    "learned_guided": ("guided", {"base": L}),
    "learned_guided_finish": ("finish", {"base": ("guided", {"base": L})}),
    "learned_guided_h40": ("guided", {"horizon": 40, "base": L}),
    "learned_guided_h80": ("guided", {"horizon": 80, "base": L}),
    "learned_guided_h120": ("guided", {"horizon": 120, "base": L}),
    "learned_hedge": ("hedge", {"base": ("learned", {"traced": True})}),
    "learned:idle_wait=true": ("learned", {"idle_wait": True}),
    **{
        f"hedge:demand=reports/2026-12-04-demand-models/{family}.json(learned:traced=true)": (
            "hedge",
            {"demand": f"reports/2026-12-04-demand-models/{family}.json", "base": ("learned", {"traced": True})},
        )
        for family in ("berlin_burst", "berlin_peak", "berlin_stream")
    },  # the hedge with an estimated demand model (docs/results.md, "Learning from the hedge")
    "greedy": ("greedy", {}),
    "insertion": ("insertion", {}),
    "batch_assignment": ("batch_assignment", {}),
    "batch_assignment+wait=1+release": ("batch_assignment", W1R),
    V: (V, {}),
    f"{V}:30": (V, {"value_price_s": 30.0}),
    f"{V}:50": (V, {"value_price_s": 50.0}),
    f"{V}:100": (V, {"value_price_s": 100.0}),
    f"{V}:150": (V, {"value_price_s": 150.0}),
    f"{V}:300": (V, {"value_price_s": 300.0}),
    f"{V}:400": (V, {"value_price_s": 400.0}),
    f"{V}:100+release": (V, {"release": True, "value_price_s": 100.0}),
    f"{V}:100+wait=0.5": (V, {"wait": 0.5, "value_price_s": 100.0}),
    f"{V}:100+wait=1": (V, {"wait": 1.0, "value_price_s": 100.0}),
    f"{V}:100+wait=2": (V, {"wait": 2.0, "value_price_s": 100.0}),
    f"{V}:100+wait=4": (V, {"wait": 4.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release": (V, {**W1R, "value_price_s": 100.0}),
    f"{V}:100+wait=2+release": (V, {"wait": 2.0, "release": True, "value_price_s": 100.0}),
    f"{V}:100+wait=0.75+release+price=1000": (
        V, {"wait": 0.75, "release": True, "unassigned_price_s": 1000.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=500": (V, {**W1R, "unassigned_price_s": 500.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=700": (V, {**W1R, "unassigned_price_s": 700.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=1000": (V, {**W1R, "unassigned_price_s": 1000.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=1500": (V, {**W1R, "unassigned_price_s": 1500.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=2000": (V, {**W1R, "unassigned_price_s": 2000.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=700+guard=600": (
        V, {**W1R, "unassigned_price_s": 700.0, "unassigned_guard_s": 600.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1+release+price=1000+guard=600": (
        V, {**W1R, "unassigned_price_s": 1000.0, "unassigned_guard_s": 600.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1.5+release+price=1000": (
        V, {"wait": 1.5, "release": True, "unassigned_price_s": 1000.0, "value_price_s": 100.0}),
    f"{V}:100+wait=1.5+release+price=1000+guard=600": (
        V, {"wait": 1.5, "release": True, "unassigned_price_s": 1000.0, "unassigned_guard_s": 600.0,
            "value_price_s": 100.0}),
    f"{V}:100+wait=2+release+price=700": (
        V, {"wait": 2.0, "release": True, "unassigned_price_s": 700.0, "value_price_s": 100.0}),
    f"{V}:100+wait=2+release+price=1000": (
        V, {"wait": 2.0, "release": True, "unassigned_price_s": 1000.0, "value_price_s": 100.0}),
    f"{V}:100+wait=2+release+price=1500": (
        V, {"wait": 2.0, "release": True, "unassigned_price_s": 1500.0, "value_price_s": 100.0}),
    f"{V}:50+wait=1+release@refit_berlin": (V, {**W1R, "value_price_s": 50.0, "value": "refit_berlin"}),
    f"{V}:100+wait=1+release@refit_berlin": (V, {**W1R, "value_price_s": 100.0, "value": "refit_berlin"}),
    f"{V}:200+wait=1+release@refit_berlin": (V, {**W1R, "value_price_s": 200.0, "value": "refit_berlin"}),
    f"{V}:50+wait=1+release@refit_both": (V, {**W1R, "value_price_s": 50.0, "value": "refit_both"}),
    f"{V}:100+wait=1+release@refit_both": (V, {**W1R, "value_price_s": 100.0, "value": "refit_both"}),
    f"{V}:200+wait=1+release@refit_both": (V, {**W1R, "value_price_s": 200.0, "value": "refit_both"}),
    # the fleet search at decision time over the chosen dispatcher (docs/results/fleet_search_val_*.csv)
    f"fleet_search({V}:100+wait=1+release+price=1000+guard=600)": ("fleet_search", {"base": (
        V, {**W1R, "unassigned_price_s": 1000.0, "unassigned_guard_s": 600.0, "value_price_s": 100.0})}),
    # the fleet search with the estimated (and, on the peak-release episodes, the true) demand model, 2 futures, the
    # candidates β = 1 and 3, the waits still owed at the horizon (docs/results/fleet_search_est_val_*.csv, _peak_)
    **{f"fleet_search:demand={model},futures=2,waits=3,end_wait=1({V}:100+wait=1+release+price=1000+guard=600)": (
        "fleet_search", {"demand": model, "futures": 2, "waits": (3.0,), "end_wait": 1.0, "base": (
            V, {**W1R, "unassigned_price_s": 1000.0, "unassigned_guard_s": 600.0, "value_price_s": 100.0})})
       for model in ("estimated", "true")},
    # a recorded learned fleet is the FILE it flew (berlin_fleet.pt, not PRETRAINED["berlin_fleet"]), or a run
    "learned:berlin_fleet": ("learned", {"source": str(SHIPPED / "berlin_fleet.pt"), "passenger_slots": "world"}),
    "learned:berlin_fleet4": ("learned", {"source": str(SHIPPED / "berlin_fleet4.pt"), "passenger_slots": "world"}),
    "learned:berlin_fleet+window24": ("learned", {"source": str(SHIPPED / "berlin_fleet.pt"), "passenger_window": 24}),
    "learned:berlin_fleet_hover+window24": (
        "learned", {"source": str(SHIPPED / "berlin_fleet_hover.pt"), "passenger_window": 24}),
    "learned:dagger_r2+window24": ("learned", {"source": "runs/dagger_r2/best.pt", "passenger_window": 24}),
    "learned:dagger_r4+window24": ("learned", {"source": "runs/dagger_r4/best.pt", "passenger_window": 24}),
    "learned:dagger_slow_r2+window24": ("learned", {"source": "runs/dagger_slow_r2/best.pt", "passenger_window": 24}),
    "learned:dagger_slow_s2_r3+window24": (
        "learned", {"source": "runs/dagger_slow_s2_r3/best.pt", "passenger_window": 24}),
    **{f"learned:{name}+window24": ("learned", {"source": f"runs/{name}/best.pt", "passenger_window": 24})
       for name in ("labels_r0", "labels_r1", "labels_r2", "stoplabels_r1", "stoplabels_r2", "anchored_r2",
                    "anchored_r3")},
    # a fleet policy reading the chosen dispatcher's claims, flown as a dispatcher (docs/results/fleet_claims_val.csv)
    **{f"fleet_claims:source=reports/2026-12-04-fleet-claims/{stem}.pt": (
        "fleet_claims", {"source": f"reports/2026-12-04-fleet-claims/{stem}.pt"})
       for stem in ("claims_r2", "claims_r3", "claims_hover_r2", "claims_hover_r3")},
    **{f"fleet_claims:source=reports/{path}.pt": ("fleet_claims", {"source": f"reports/{path}.pt"})
       for path in ("2026-12-04-fleet-val50/claims_hover01_r3", "2026-12-04-fleet-val50/claims_hover01_r5",
                    "2026-12-04-fleet-val50/claims_hover004_r3", "2026-12-04-fleet-finetune/ppoA_last",
                    "2026-12-04-fleet-finetune/ppoB_last")},
    "fleet_claims:source=reports/2026-12-04-fleet-val50/claims_hover01_r3.pt,hover_when_idle=true": (
        "fleet_claims", {"source": "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt", "hover_when_idle": True}),
    # the claims networks reading onward's heading mark, the last also stepping aside
    # (reports/2026-12-05-fleet-onward-marks)
    **{f"fleet_claims:source=reports/{path}.pt,heading=onward{way}": (
        "fleet_claims", {"source": f"reports/{path}.pt", "heading": "onward", **({"make_way": True} if way else {})})
       for path, way in (("2026-12-04-fleet-val50/claims_hover01_r3", ""),
                         ("2026-12-05-fleet-onward-marks/marks_dagger_r3", ""),
                         ("2026-12-04-fleet-val50/claims_hover01_r3", ",make_way=true"))},
    **{"batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,unassigned_guard_s=600,"
       f"heading={rule}": ("batch_assignment_value", {"value_price_s": 100.0, "wait": 1.0, "release": True,
                                                      "unassigned_price_s": 1000.0, "unassigned_guard_s": 600.0,
                                                      "heading": rule})
       for rule in ("table", "onward")},
    "learned:hover_ft+window24": ("learned", {"source": "runs/hover_ft/best.pt", "passenger_window": 24}),
    "learned:mix_ft+window24": ("learned", {"source": "runs/mix_ft/best.pt", "passenger_window": 24}),
    "learned:switched+window24": ("learned", {"source": "runs/switched/best.pt", "passenger_window": 24}),
}  # fmt: skip
LABELS = ("CPTSP", "PDPCC", "MSHA-RL", "straight (RL order)")  # the paper's published figures: no policy


def test_the_recorded_names_are_exactly_those_of_the_committed_csvs() -> None:
    recorded = set()
    for path in (ROOT / "docs" / "results").rglob("*.csv"):
        with path.open(newline="") as f:
            for row in csv.DictReader(f):
                recorded |= {row[c] for c in ("method", "dispatcher") if row.get(c)}
    assert recorded == set(RECORDED) | set(LABELS)
    assert len(recorded) == 98


@pytest.mark.parametrize("name", sorted(RECORDED))
def test_every_recorded_name_reads_as_its_call_and_writes_back(name: str) -> None:
    assert parse(name) == RECORDED[name]
    assert parse(format(*RECORDED[name])) == RECORDED[name]


@pytest.mark.parametrize("label", LABELS)
def test_a_published_figures_label_is_no_policy(label: str) -> None:
    with pytest.raises(PolicyNameError, match="published figure"):
        parse(label)


def test_every_registered_default_survives_format_then_parse() -> None:
    for name, (_, cls) in policies.available().items():
        defaults = {f.name: getattr(cls(), f.name) for f in dataclasses.fields(cls)}
        for options in ({}, defaults):
            assert parse(format(name, options)) == (name, options), name


def test_the_grammar_reads_options_bases_and_greedy_of_a_base() -> None:
    assert parse("batch_assignment:wait=1,release=true,unassigned_price_s=1000") == (
        "batch_assignment", {"wait": 1.0, "release": True, "unassigned_price_s": 1000.0})  # fmt: skip
    assert parse("hedge:futures=8,commit=4(learned:source=berlin)") == (
        "hedge", {"futures": 8, "commit": 4, "base": ("learned", {"source": "berlin"})})  # fmt: skip
    assert parse("best_known:beams=256;1024,rank_slack=0.5") == ("best_known", {"beams": (256, 1024),
                                                                                "rank_slack": (0.5,)})  # fmt: skip
    assert parse("guided:horizon=none(learned)") == ("guided", {"horizon": None, "base": L})
    # greedy in front of a base is the argmax wrapper; bare greedy stays the fleet dispatcher
    assert parse("greedy(learned:source=berlin_stops)") == ("argmax", {"base": ("learned", {"source": "berlin_stops"})})
    assert policies.available()["greedy"][0] == "dispatcher"
    assert policies.available()["argmax"][0] == "search"
    assert (
        format("finish", {"beam": 8, "base": ("guided", {"top_k": 4, "base": L})})
        == "finish:beam=8(guided:top_k=4(learned))"
    )


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("replann", r"unknown policy 'replann'; the registered policies are .*replan.*batch_assignment"),
        ("replan:width=3", r"policy 'replan' has no option 'width'; its options are: beam, rank_slack"),
        ("replan:beam=wide", r"policy 'replan': beam='wide' is no int; give one \(e\.g\. beam=64\)"),
        ("replan:beam=0", r"policy 'replan': beam=0 .*"),
        ("batch_assignment:unassigned_guard_s=600", r"give both"),
        ("insertion:wait=1e9", r"wait=.* too large"),
        ("batch_assignment+wait=x", r"\+wait=<…> takes a finite number"),
        ("batch_assignment+walk=1", r"unknown option 'walk=1'"),
        ("greedy+release", r"belong to the schedule dispatchers, not to 'greedy'"),
        ("replan(learned)", r"'replan' is a planner; only a search takes a base"),
        ("guided(learned", r"a base goes in parentheses at the end"),
        ("replan:beam", r"'beam' is no OPTION=VALUE"),
        ("replan:beam=1,beam=2", r"option 'beam' given twice"),
        ("", r"name a policy"),
        ("learned:source=berlin,passenger_window=24,passenger_slots=6", r"give one"),
    ],
)
def test_a_bad_name_is_refused_in_one_line_naming_it(text: str, pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern) as err:
        parse(text)
    assert "\n" not in str(err.value)


def test_make_refuses_unknown_options_and_a_base_on_a_planner() -> None:
    with pytest.raises(PolicyNameError, match="has no option 'beem'; its options are: beam, rank_slack"):
        policies.make("replan", beem=3)
    with pytest.raises(PolicyNameError, match="'replan' is a planner, which searches over no base"):
        policies.make("replan", base="learned")
    with pytest.raises(PolicyNameError, match="kind 'oracle' is none of"):
        policies.available("oracle")
