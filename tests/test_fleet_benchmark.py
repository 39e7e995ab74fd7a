"""eval.fleet_benchmark's table: per setting and dispatcher, means with 95 % intervals, by hand."""

from __future__ import annotations

import math

import pytest

from uamfleet.cli.fleet_benchmark import COLUMNS, Args, main, markdown


def _row(seed: int, dispatcher: str, service: float, wait_p95: float) -> dict[str, object]:
    row: dict[str, object] = {c: 1.0 for c in COLUMNS}
    row.update({"family": "berlin", "setting": "2x12", "taxis": 2, "seed": seed, "dispatcher": dispatcher,
                "service_pct": service, "wait_p95_s": wait_p95, "detour": 1.25, "occupancy": 0.5,
                "decision_p50_ms": 0.2 * seed, "decision_max_ms": 3.0 * seed})  # fmt: skip
    return row


def test_markdown_by_hand():
    rows = [_row(1, "insertion", 100.0, 60.0), _row(2, "insertion", 50.0, 80.0), _row(1, "greedy", 100.0, 50.0)]
    text = markdown(rows, "cmd", math.nan)
    half = 1.96 * math.sqrt(((60 - 70) ** 2 + (80 - 70) ** 2) / 1) / math.sqrt(2)
    line = next(x for x in text.splitlines() if "| insertion |" in x)
    cells = [c.strip() for c in line.split("|")[1:-1]]
    assert cells[:5] == ["berlin", "2x12", "insertion", "2", "50"]  # one of two episodes delivered everyone
    assert cells[5] == f"75.0 ± {1.96 * 25.0 * math.sqrt(2) / math.sqrt(2):,.1f}"
    assert cells[7] == f"70.0 ± {half:,.1f}"
    assert cells[8] == "125.0 ± 0.0 %" and cells[10] == "50.0 ± 0.0 %"
    assert cells[-1] == "0.3 / 6"  # median of the episodes' p50 (0.2, 0.4), max of their maxima
    assert text.index("| greedy |") < text.index("| insertion |")  # dispatchers in their fixed order


def test_unknown_setting_is_named():
    for bad in ("3by7", "0x6", "x6", "4x"):
        with pytest.raises(ValueError, match=rf"--settings setting '{bad}' is not <taxis>x<requests> with both >= 1"):
            main(Args(settings=(bad,)))


def test_settings_beyond_the_table_are_taxis_x_requests():
    from uamfleet.cli.fleet_benchmark import setting_size

    assert setting_size("4x24") == (4, 24) and setting_size("8x96") == (8, 96) and setting_size("3x7") == (3, 7)


def test_fleet_episodes_fly_through_the_shield_when_asked() -> None:
    """--separation shield: every flown episode has the shield (zero violations); make_fleet_instance's own default
    stays as the earliest tables recorded it (no shield)."""
    from uamfleet.cli.fleet_benchmark import run_episode_set
    from uamfleet.config import ConfigError
    from uamfleet.instances import make_fleet_instance

    assert make_fleet_instance("berlin", 2000000, 4, 24).separation == "none"
    assert make_fleet_instance("berlin", 2000000, 4, 24, separation="shield").separation == "shield"
    with pytest.raises(ConfigError, match="separation"):
        make_fleet_instance("berlin", 2000000, 4, 24, separation="fence")
    shielded = run_episode_set(("berlin", "4x24", 2000000, ("greedy",), (), "shield", False))
    assert shielded[0]["separation_violations"] == 0 and shielded[0]["service_pct"] == 100.0
    assert shielded[0]["hover_actions"] == 0  # no hover action unless asked
    hovering = run_episode_set(("berlin", "4x24", 2000000, ("greedy",), (), "shield", True))
    assert hovering[0]["separation_violations"] == 0 and hovering[0]["service_pct"] == 100.0
    assert hovering[0]["hover_actions"] > 0 and hovering[0]["td_m"] < shielded[0]["td_m"]  # idle taxis stay put


def test_the_command_flies_the_fleet_presets_rules_by_default() -> None:
    """A new user's `uamfleet fleet-bench` flies the *_fleet presets' rules (shield, idle taxis hover); the rules
    of the earliest tables are asked for by name, and the printed re-run command names whichever differ."""
    from uamfleet.cli.fleet_benchmark import rerun_command
    from uamfleet.presets import make_config

    preset = make_config("berlin_fleet")
    assert (Args().separation, Args().hover_action) == (preset.separation, preset.hover_action) == ("shield", True)
    default = rerun_command(Args(settings=("2x6",), count=1))
    assert "--separation" not in default and "hover-action" not in default
    old = rerun_command(Args(settings=("2x6",), count=1, separation="none", hover_action=False))
    assert old.endswith("--separation none --no-hover-action")


def test_dispatchers_are_read_in_the_grammar_and_as_recorded() -> None:
    """A recorded name and its call in the grammar build the same dispatcher; a name of no dispatcher is refused
    before anything flies (learned fleets come by --checkpoints)."""
    from uamfleet.cli.fleet_benchmark import _check_names, dispatcher

    recorded = dispatcher("batch_assignment_value:100+wait=1+release+price=1000", 2, None, 600.0)
    grammar = dispatcher(
        "batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000", 2, None, 600.0
    )
    for policy in (recorded, grammar):
        assert (policy.wait_weight, policy.assign_on_release, policy.unassigned_price_s) == (1.0, True, 1000.0)
        assert (policy.value.price_s, policy.value.arrival_window_s) == (100.0, 600.0)
    _check_names(Args(count=1, dispatchers=("greedy", "insertion:wait=2")))
    with pytest.raises(ValueError, match=r"unknown --dispatchers \['learned:berlin_fleet', 'guided\(learned\)'\]"):
        _check_names(Args(count=1, dispatchers=("learned:berlin_fleet", "guided(learned)")))


def test_workers_run_one_torch_thread_unless_told(tmp_path) -> None:
    """--threads (default 1) is every worker's torch thread count: torch's default of every core made two workers'
    threads spin against each other (reports/2026-12-04-decision-time-maps); 0 is refused before anything flies."""
    import torch

    from uamfleet.checks import ConfigError
    from uamfleet.cli.fleet_benchmark import limit_threads

    assert Args().threads == 1
    with pytest.raises(ConfigError, match=r"--threads=0 must be an integer in \[1, 1024\]"):
        main(Args(threads=0, count=1, settings=("2x4",), out_csv=tmp_path / "never.csv"))
    assert not (tmp_path / "never.csv").exists()
    before = torch.get_num_threads()
    try:
        limit_threads(1)
        assert torch.get_num_threads() == 1
        limit_threads(2)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
