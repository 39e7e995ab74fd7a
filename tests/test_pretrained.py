"""The shipped pretrained planner: it loads safely in one call, plans a user's own instance at any threshold, and the
main job's report of it runs."""

from __future__ import annotations

import pytest
from pathlib import Path
import torch

import uamfleet
from uamfleet.cli.paper_numbers import PAPER_TABLE_II
from uamfleet.cli.quickstart import generalist_report
from uamfleet.metrics import episode_metrics
from uamfleet.zoo import PRETRAINED, pretrained_path


def test_every_shipped_file_loads_with_weights_only() -> None:
    for name in PRETRAINED:
        payload = torch.load(pretrained_path(name), weights_only=True)
        assert payload["optimizer"] == {}  # stripped: a policy to fly, not a run to resume
        assert pretrained_path(name).stat().st_size < 5_000_000
    with pytest.raises(ValueError, match="ships"):
        pretrained_path("paris")


@pytest.mark.parametrize("threshold", [-7.0, -4.0])
def test_the_berlin_generalist_flies_berlin_p4_zero_shot(threshold: float) -> None:
    planner = uamfleet.pretrained("berlin")
    cfg = uamfleet.make_config("berlin_p4", sinr_min_db=threshold)
    m = episode_metrics(planner.fly(cfg), cfg.radio, threshold_db=threshold)
    assert m.pr_pct == 100.0
    assert m.td_m <= PAPER_TABLE_II["berlin"]["MSHA-RL"][threshold][0]  # the paper's learned planner on its instance


def test_the_berlin_generalist_plans_a_users_own_instance() -> None:
    planner = uamfleet.pretrained("berlin")
    cfg = uamfleet.make_config(
        "berlin_random", num_taxis=1, sinr_min_db=-6.0, starts_m=((2600.0, 1500.0),),
        requests=[(0, (2220.0, 1400.0), (1850.0, 1100.0)), (3, (1450.0, 2000.0), (1270.0, 450.0))],
    )  # fmt: skip
    traj = planner.fly(cfg)
    m = episode_metrics(traj, cfg.radio, threshold_db=-6.0)
    assert m.pr_pct == 100.0 and m.num_requests == 2
    assert traj.sinr_min_db == -6.0


def test_the_main_jobs_generalist_report_runs(capsys: pytest.CaptureFixture[str]) -> None:
    result = generalist_report(test_count=3, planner_csv=Path("docs/results/missing.csv"))
    out = capsys.readouterr().out
    assert "Berlin P4 (zero-shot)" in out and "generalist (shipped)" in out
    assert result["all_delivered_pct"] == 100.0 and result["td_m"] > 0


def test_the_berlin_fleet_policy_serves_a_fleet_instance() -> None:
    from uamfleet.instances import make_fleet_instance

    fleet = uamfleet.pretrained("berlin_fleet4")
    cfg = make_fleet_instance("berlin", 2_000_000, num_taxis=4, num_requests=8)
    m = episode_metrics(fleet.fly(cfg), cfg.radio)
    assert m.num_requests == 8 and m.pr_pct == 100.0
    # any fleet its spec reads (6 rows per taxi, no window): 12 rows at 2 taxis, a 13th request refused in one line
    two = make_fleet_instance("berlin", 2_000_000, num_taxis=2, num_requests=4)
    assert episode_metrics(fleet.fly(two), two.radio).pr_pct == 100.0
    with pytest.raises(ValueError, match="the world has 13 passenger rows; this policy reads 12"):
        fleet.fly(make_fleet_instance("berlin", 2_000_000, num_taxis=2, num_requests=13))


def test_the_shipped_fleet_policy_serves_any_fleet_size_and_asks_for_the_hover_action() -> None:
    from uamfleet.instances import make_fleet_instance

    fleet = uamfleet.pretrained("berlin_fleet")
    assert fleet.passenger_window == 24 and fleet.net.cfg.hover_logit  # the window comes with the checkpoint
    for taxis, requests in ((8, 16), (2, 30)):  # 30 > its 24 rows: the window reads the nearest
        cfg = make_fleet_instance("berlin", 2_000_001, num_taxis=taxis, num_requests=requests, hover_action=True)
        m = episode_metrics(fleet.fly(cfg), cfg.radio)
        assert m.num_requests == requests and m.pr_pct == 100.0
    with pytest.raises(ValueError, match=r"hover_action=True"):
        fleet.fly(make_fleet_instance("berlin", 2_000_001, num_taxis=2, num_requests=4, hover_action=False))


def test_a_fleet_instance_has_its_fleet_presets_hover_so_the_shipped_fleet_policy_flies_it_as_made() -> None:
    from uamfleet.instances import make_fleet_instance

    for family in ("berlin", "detroit3gpp"):
        assert uamfleet.make_config(f"{family}_fleet").hover_action is True
    cfg = make_fleet_instance("berlin", 2_000_001, num_taxis=2, num_requests=4)
    assert cfg.hover_action is True and cfg.num_actions == 17
    m = episode_metrics(uamfleet.pretrained("berlin_fleet").fly(cfg), cfg.radio)
    assert m.num_requests == 4 and m.pr_pct == 100.0
    assert make_fleet_instance("berlin", 2_000_001, num_taxis=2, num_requests=4, hover_action=False).num_actions == 16


def test_the_first_shipped_fleet_policy_serves_its_own_and_other_fleet_sizes() -> None:
    from uamfleet.instances import make_fleet_instance

    fleet = uamfleet.pretrained("berlin_fleet_v1")
    assert fleet.num_taxis == 4
    for taxis, requests in ((4, 8), (2, 4)):
        cfg = make_fleet_instance("berlin", 2_000_001, num_taxis=taxis, num_requests=requests)
        m = episode_metrics(fleet.fly(cfg), cfg.radio)
        assert m.num_requests == requests and m.pr_pct == 100.0
