"""eval.benchmark's table: TD / best-known per instance and 95 % intervals, by hand."""

from __future__ import annotations

import math

from uamfleet.cli.benchmark import Args, tasks
from uamfleet.cli.benchmark_tables import markdown, summary


def _row(instance: str, method: str, td: float, pr: float = 100.0) -> dict[str, object]:
    return {"set": "berlin test", "instance": instance, "threshold_db": -3.0, "feasibility": "endpoint_block",
            "num_requests": 4, "method": method, "pr_pct": pr, "td_m": td, "att_s": 100.0, "awt_s": 50.0,
            "connectivity_pct": 99.0, "lower_bound_m": 900.0, "steps": 10, "policy_s": 1.0,
            "decision_p50_ms": 0.1, "decision_max_ms": 5.0}  # fmt: skip


def test_summary_ratios_and_intervals_by_hand():
    rows = [_row("1", "best_known", 1000.0), _row("2", "best_known", 2000.0),
            _row("1", "raster_opt", 1100.0), _row("2", "raster_opt", 3000.0),
            _row("1", "replan", 1200.0), _row("2", "replan", 9000.0, pr=50.0)]  # fmt: skip
    by = {s["method"]: s for s in summary(rows, ("set", "feasibility"))}
    assert math.isclose(by["raster_opt"]["ratio_mean"], 1.3) and math.isclose(by["raster_opt"]["ratio_max"], 1.5)
    half = 1.96 * math.sqrt(((1100 - 2050) ** 2 + (3000 - 2050) ** 2) / 1) / math.sqrt(2)
    assert by["raster_opt"]["td"] == f"2,050.0 ± {half:,.1f}"
    assert by["replan"]["ratio_mean"] == 1.2  # the undelivered instance is left out of the ratio
    assert by["replan"]["all_delivered_pct"] == 50.0
    assert math.isclose(by["best_known"]["over_lb"], 1500.0 / 900.0)
    text = markdown(rows, "cmd", math.nan)
    assert "| raster_opt | 100.0 |" in text and "1.300 |" in text


def test_tasks_pick_fixed_instances_by_rule_scenario_and_threshold():
    chosen = tasks(Args(count=2, fixed=True, fixed_rules=("segment_raster",), fixed_scenarios=("berlin_p4",),
                        fixed_thresholds=(-3.0, -7.0)))  # fmt: skip
    assert [t[0] for t in chosen] == ["test", "test", "fixed", "fixed"]
    assert [(t[1], t[3], t[4]) for t in chosen[2:]] == [("berlin_p4", -7.0, "segment_raster"),
                                                         ("berlin_p4", -3.0, "segment_raster")]  # fmt: skip


def test_the_hedge_flies_an_instance_and_skips_a_fixed_scenario(capsys) -> None:
    """learned_hedge needs the family's demand model: flown on an instance, refused (with a line) on a fixed one."""
    from uamfleet.cli.benchmark import Job, job_options, run_instance
    from uamfleet.zoo import pretrained_path

    chosen = tasks(Args(count=1, fixed=True, fixed_rules=("endpoint_block",), fixed_scenarios=("berlin_p4",),
                        fixed_thresholds=(-3.0,)))  # fmt: skip
    for task in chosen:
        rows = run_instance(Job(task, ("learned_hedge",), pretrained_path("berlin"), job_options(Args())))
        if task[0] == "fixed":
            assert rows == [] and "learned_hedge skipped on berlin_p4@-3dB" in capsys.readouterr().out
        else:
            assert [r["method"] for r in rows] == ["learned_hedge"] and rows[0]["pr_pct"] == 100.0
