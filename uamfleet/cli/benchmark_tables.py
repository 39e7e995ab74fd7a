"""The yardstick table of a benchmark run: per (set, method) means with 95 % intervals, TD / best-known per
instance and the paper's fixed instances, as Markdown (the results pages regenerate the same tables from the CSVs).

Rows are those of :func:`uamfleet.cli.benchmark.run_instance` (one per instance and method)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from uamfleet.cli._common import fmt


def _mean(values: np.ndarray) -> float:
    """The mean, NaN (printed "–") for no values."""
    return float(values.mean()) if len(values) else math.nan


def ci(values: np.ndarray) -> str:
    """The finite values' mean with its 95 % interval (normal approximation, 1.96 standard errors), "–" for none."""
    values = values[np.isfinite(values)]
    if not len(values):
        return "–"
    half = 1.96 * values.std(ddof=1) / math.sqrt(len(values)) if len(values) > 1 else 0.0
    return f"{values.mean():,.1f} ± {half:,.1f}"


def _td_ratios(sel: list[dict[str, Any]], best: dict[tuple[str, str, str], dict[str, Any]]) -> np.ndarray:
    """TD / best-known TD of each row whose instance has a best-known row, both delivering everyone."""
    ratios = []
    for r in sel:
        b = best.get((r["set"], r["instance"], r["feasibility"]))
        if b is not None and r["pr_pct"] >= 100.0 and b["pr_pct"] >= 100.0:
            ratios.append(r["td_m"] / b["td_m"])
    return np.array(ratios)


def _ratio_stats(ratio: np.ndarray) -> dict[str, float]:
    """Mean, 95th percentile and worst of the TD / best-known ratios (NaN without any)."""
    if not len(ratio):
        return {"ratio_mean": math.nan, "ratio_p95": math.nan, "ratio_max": math.nan}
    return {
        "ratio_mean": float(ratio.mean()), "ratio_p95": float(np.percentile(ratio, 95)),
        "ratio_max": float(ratio.max()),
    }  # fmt: skip


def summary(rows: list[dict[str, Any]], group: tuple[str, ...]) -> list[dict[str, Any]]:
    """One line per (group..., method): means with 95 % intervals and TD / best-known per instance."""
    best = {(r["set"], r["instance"], r["feasibility"]): r for r in rows if r["method"] == "best_known"}
    out = []
    keys = dict.fromkeys((*tuple(r[g] for g in group), r["method"]) for r in rows)
    for key in keys:
        sel = [r for r in rows if (*tuple(r[g] for g in group), r["method"]) == key]
        arr = {c: np.array([float(r[c]) for r in sel]) for c in ("pr_pct", "td_m", "att_s", "awt_s",
                                                                  "connectivity_pct", "lower_bound_m")}  # fmt: skip
        p50 = [r["decision_p50_ms"] for r in sel]
        out.append({
            **dict(zip((*group, "method"), key, strict=True)), "n": len(sel),
            "all_delivered_pct": 100.0 * float(np.mean(arr["pr_pct"] >= 100.0)),
            "pr": ci(arr["pr_pct"]), "td": ci(arr["td_m"]), "att": ci(arr["att_s"]), "awt": ci(arr["awt_s"]),
            "conn": ci(arr["connectivity_pct"]), "lb": float(arr["lower_bound_m"].mean()),
            "over_lb": _mean((arr["td_m"] / arr["lower_bound_m"])[arr["pr_pct"] >= 100.0]),
            **_ratio_stats(_td_ratios(sel, best)),
            "decision_p50_ms": float(np.median(p50)), "decision_max_ms": max(r["decision_max_ms"] for r in sel),
            "policy_s": float(np.mean([r["policy_s"] for r in sel])),
        })  # fmt: skip
    return out


def command_header(command: str, wall_s: float, note: str = "") -> list[str]:
    """The lines that open a results section: the command in a code block, then its wall-clock time if known."""
    lines = ["```bash", command, "```", ""]
    if math.isfinite(wall_s):
        lines += [f"Wall-clock: {wall_s / 60:.1f} min{note}.", ""]
    return lines


def markdown(rows: list[dict[str, Any]], command: str, wall_s: float, note: str = "") -> str:
    lines = command_header(command, wall_s, note)
    random_rows = [r for r in rows if r["set"] != "fixed"]
    if random_rows:
        lines += _random_table(random_rows)
    fixed = [r for r in rows if r["set"] == "fixed"]
    if fixed:
        lines += _fixed_table(fixed)
    return "\n".join(lines)


def _random_table(random_rows: list[dict[str, Any]]) -> list[str]:
    """The summary table of the generated instances, one line per method."""
    lines = [
        f"### {random_rows[0]['set']} instances ({len({r['instance'] for r in random_rows})}, "
        f"{random_rows[0]['feasibility']} rule)",
        "",
        "| method | all delivered % | PR % | TD m | ATT s | AWT s | conn. % | TD / best-known mean | p95 | worst "
        "| lower bound m (mean) | TD / lower bound mean | decision p50 / max ms | s per instance |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for s in summary(random_rows, ("set", "feasibility")):
        lines.append(
            f"| {s['method']} | {s['all_delivered_pct']:.1f} | {s['pr']} | {s['td']} | {s['att']} | {s['awt']} | "
            f"{s['conn']} | {fmt(s['ratio_mean'], '.3f')} | {fmt(s['ratio_p95'], '.3f')} | "
            f"{fmt(s['ratio_max'], '.3f')} | {fmt(s['lb'], ',.0f')} | {fmt(s['over_lb'], '.3f')} | "
            f"{s['decision_p50_ms']:.1f} / {s['decision_max_ms']:,.0f} | "
            f"{s['policy_s']:.1f} |"
        )
    return [*lines, ""]


def _fixed_table(fixed: list[dict[str, Any]]) -> list[str]:
    """The paper's fixed instances, one line per instance and rule, one column per method."""
    methods = list(dict.fromkeys(r["method"] for r in fixed))
    lines = [
        "### The paper's fixed instances: TD m (PR % where below 100)",
        "",
        "| instance | rule | lower bound | " + " | ".join(methods) + " |",
        "|---|---|---:|" + "---:|" * len(methods),
    ]
    for inst in dict.fromkeys((r["instance"], r["feasibility"]) for r in fixed):
        cells = {r["method"]: r for r in fixed if (r["instance"], r["feasibility"]) == inst}
        bound = next(iter(cells.values()))["lower_bound_m"]
        tds = [
            f"{c['td_m']:,.0f}" + ("" if c["pr_pct"] >= 100 else f" (PR {c['pr_pct']:.0f})")
            for c in (cells[m] for m in methods)
        ]
        lines.append(f"| {inst[0]} | {inst[1]} | {bound:,.0f} | " + " | ".join(tds) + " |")
    return [*lines, ""]
