"""``--map FILE|NAME`` on the commands: the packaged Munich map and a map file by path fly through each, their
instances are the map family's (uamfleet.instances.map_family), the map's provenance is printed above the results,
and a bad name or file is refused in one line with exit status 2."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from uamfleet.cli import benchmark, fleet_benchmark, render, rollout
from uamfleet.instances import make_fleet_instance, make_instance, map_family, split_seeds
from uamfleet.radio import RADIO_MAPS, load_radio_map, save_radio_map_npz


@pytest.fixture(scope="module")
def city(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A map file of a city (the Munich raster under another name)."""
    return save_radio_map_npz(load_radio_map("munich"), tmp_path_factory.mktemp("maps") / "city.npz")


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("which", ["munich", "file"])
def test_benchmark_flies_the_test_instances_of_a_map(which: str, city: Path, tmp_path: Path, capsys) -> None:
    name = "munich" if which == "munich" else str(city)
    out = tmp_path / "b.csv"
    argv = ["--map", name, "--count", "2", "--jobs", "1", "--methods", "straight", "raster_opt", "--out-csv", str(out)]
    assert benchmark.cli(argv) == 0
    rows = _rows(out)
    assert [(r["instance"], r["method"]) for r in rows] == [
        (str(seed), method) for seed in split_seeds("test", 2) for method in ("straight", "raster_opt")
    ]
    assert {r["set"] for r in rows} == {f"{name} test"}
    expected = [make_instance(name, seed).sinr_min_db for seed in split_seeds("test", 2)]
    assert [float(r["threshold_db"]) for r in rows[::2]] == expected
    assert all(t in map_family(name).thresholds_db for t in expected)
    printed = capsys.readouterr().out
    where = "packaged map 'munich'" if which == "munich" else f"map file {city}"
    head, _, table = printed.partition(f"Map: {where}: 148 x 121 cells of 10 m, operating square 1200 m")
    assert f"--map {name} " in head and "| straight |" in table  # the command above, the provenance, the table
    assert "Sionna RT" in table.split("\n")[0]  # the map's own record on the provenance line


@pytest.mark.parametrize("which", ["munich", "file"])
def test_fleet_benchmark_flies_the_fleet_instances_of_a_map(which: str, city: Path, tmp_path: Path, capsys) -> None:
    name = "munich" if which == "munich" else str(city)
    out = tmp_path / "f.csv"
    argv = ["--map", name, "--count", "1", "--settings", "2x12", "--jobs", "1", "--dispatchers", "greedy",
            "--out-csv", str(out)]  # fmt: skip
    assert fleet_benchmark.cli(argv) == 0
    [row] = _rows(out)
    seed = split_seeds("test", 1)[0]
    assert (row["family"], row["setting"], int(row["seed"])) == (name, "2x12", seed)
    assert float(row["threshold_db"]) == make_fleet_instance(name, seed, 2, 12).sinr_min_db
    printed = capsys.readouterr().out
    assert "Map: " in printed and printed.index("Map: ") < printed.index("| family |")


@pytest.mark.parametrize("which", ["munich", "file"])
def test_rollout_flies_a_map(which: str, city: Path, capsys) -> None:
    name = "munich" if which == "munich" else str(city)
    [row] = rollout.main(rollout.Args(map=name, policy="replan", episodes=1))
    assert row["pr_pct"] == 100.0
    out = capsys.readouterr().out
    # the default scenario becomes one taxi on random demand, at the map family's strictest threshold
    threshold = map_family(name).thresholds_db[-1]
    assert out.startswith("Map: ") and f"berlin_instances on munich: 1 taxi(s), γ_T = {threshold:g} dB" in out


def test_render_flies_a_map(city: Path, tmp_path: Path, capsys) -> None:
    written = render.main(render.Args(map=str(city), policy="straight", out=tmp_path / "city.html"))
    assert written["html"].is_file()
    out = capsys.readouterr().out
    assert out.startswith(f"Map: map file {city}: ") and "map: munich" in out


@pytest.mark.parametrize(
    ("command", "argv"),
    [
        (benchmark.cli, ["--count", "1", "--out-csv", "b.csv"]),
        (fleet_benchmark.cli, ["--count", "1", "--settings", "1x6", "--out-csv", "f.csv"]),
        (rollout.cli, ["--episodes", "1"]),
        (render.cli, ["--out", "r.html"]),
    ],
)
def test_a_bad_map_is_refused_in_one_line(command, argv: list[str], tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert command([*argv, "--map", "atlantis"]) == 2
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1 and ": error: --map 'atlantis': no packaged map of that name and no such map file" in err
    )
    assert "munich" in err and "uamfleet-radio-map" in err
    assert list(tmp_path.iterdir()) == []  # refused before anything was written


def test_a_file_that_is_no_map_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "notes.npz"
    bad.write_text("not an archive")
    assert rollout.cli(["--map", str(bad), "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--map {bad}: cannot read radio map" in err


def test_a_fixed_scenario_is_refused_on_another_map(capsys) -> None:
    assert rollout.cli(["--map", "munich", "--scenario", "detroit_p5", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a fixed scenario's stops lie on its own map" in err


def test_train_flies_a_map_file_and_its_validation_instances(city: Path, tmp_path: Path, capsys) -> None:
    from uamfleet.cli import train
    from uamfleet.rl.checkpoint import Checkpoint
    from uamfleet.rl.legacy import checkpoint_args

    argv = ["--scenario", "berlin_instances", "--map", str(city), "--total-timesteps", "64", "--num-envs", "4",
            "--num-steps", "16", "--eval-every", "1", "--curve-instances", "2", "--run-dir", str(tmp_path),
            "--threads", "1"]  # fmt: skip
    assert train.cli(argv) == 0
    assert capsys.readouterr().out.startswith(f"Map: map file {city}: 148 x 121 cells of 10 m")
    [run] = list(tmp_path.iterdir())
    assert run.name == "city_berlin_instances_defaultdB_de_msfea_s1"
    saved = checkpoint_args(Checkpoint.load(run / "best.pt"))
    assert saved.env.map == str(city) and saved.curve_family_name() == str(city)
    cfg = saved.env_overrides()
    assert cfg["radio"] == str(city) and cfg["sinr_min_db"] == map_family(str(city)).thresholds_db[-1]
    [row] = _rows(run / "progress.csv")
    assert float(row["val_td_m"]) > 0 and 0 <= float(row["val_pr_pct"]) <= 100  # the map's validation instances


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--scenario", "berlin_instances", "--map", "atlantis"], "--map='atlantis': no packaged map of that name"),
        (["--scenario", "detroit_p5", "--map", "munich"], "a fixed scenario's stops lie on its own map"),
        (["--scenario", "berlin_instances", "--map", "munich", "--eval-instances", "5"],
         "with --curve-instances N, --eval-instances 0"),
    ],
)  # fmt: skip
def test_train_refuses_a_bad_map_in_one_line(extra: list[str], message: str, tmp_path: Path, capsys) -> None:
    from uamfleet.cli import train

    assert train.cli([*extra, "--run-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", RADIO_MAPS)
def test_every_packaged_city_flies_its_test_instances_from_the_benchmark(name: str, tmp_path: Path) -> None:
    out = tmp_path / "b.csv"
    argv = ["--map", name, "--count", "2", "--jobs", "1", "--methods", "straight", "--out-csv", str(out)]
    assert benchmark.cli(argv) == 0
    rows = _rows(out)
    assert [int(r["instance"]) for r in rows] == split_seeds("test", 2)
    assert all(float(r["pr_pct"]) == 100.0 for r in rows)
    assert [float(r["threshold_db"]) for r in rows] == [
        make_instance(name, s).sinr_min_db for s in split_seeds("test", 2)
    ]


def test_expert_iteration_labels_and_validates_on_the_map_family(city: Path, monkeypatch, capsys) -> None:
    from uamfleet.cli import expert_iteration as exit_cli

    seen = []

    def fake(opts):  # the run itself is the expert iteration's (tests/rl/test_expert_iteration.py)
        seen.append(opts)
        return {"round": 0, "val_td_m": 1.0, "vs_replan_m": 0.0, "vs_replan_ci_m": 0.0}

    monkeypatch.setattr(exit_cli, "expert_iteration", fake)
    assert exit_cli.cli(["--map", str(city), "--run-name", "t"]) == 0
    assert [opts.family for opts in seen] == [str(city)]
    assert capsys.readouterr().out.startswith(f"Map: map file {city}: ")
    assert exit_cli.cli(["--map", "atlantis"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--map 'atlantis': no packaged map of that name" in err and len(seen) == 1


def test_imitate_rolls_out_and_validates_on_a_map(city: Path, tmp_path: Path, capsys) -> None:
    from uamfleet.cli import imitate

    argv = ["--map", str(city), "--envs-per-threshold", "1", "--rounds", "1", "--steps-per-round", "6",
            "--eval-instances", "2", "--epochs", "1", "--minibatch", "16", "--run-dir", str(tmp_path),
            "--run-name", "tiny"]  # fmt: skip
    assert imitate.cli(argv) == 0
    assert capsys.readouterr().out.startswith(f"Map: map file {city}: ")
    rows = _rows(tmp_path / "tiny" / "progress.csv")
    assert len(rows) == 2 and float(rows[0]["val_pr_pct"]) > 0  # the start and round 0, on the map's instances
    assert imitate.cli(["--map", "atlantis", "--run-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--map='atlantis': no packaged map of that name" in err


def test_quickstart_trains_and_flies_the_test_instances_of_a_map(city: Path, tmp_path: Path, capsys) -> None:
    from uamfleet.cli import quickstart

    argv = ["--map", str(city), "--total-timesteps", "2048", "--test-count", "2", "--run-dir", str(tmp_path)]
    assert quickstart.cli(argv) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"Map: map file {city}: ")
    threshold = map_family(str(city)).thresholds_db[-1]
    assert f"on berlin_instances on {city} at {threshold:g} dB" in out
    table = out.split("test instances of its family")[1]
    for name in ("replan", "raster_opt", "MSHA-PPO (ours)", "generalist (shipped, zero-shot)"):
        assert f"\n{name} " in table
    saved = _rows(tmp_path / "quickstart" / "progress.csv")
    assert len(saved) == 2  # the start's evaluation and one iteration


RAY_TRACED_CITIES = ("munich", "munich_3km", "san_francisco")


@pytest.mark.parametrize("name", RAY_TRACED_CITIES)
def test_every_packaged_city_flies_through_rollout_fleet_bench_and_render(name: str, tmp_path: Path, capsys) -> None:
    """The cheap commands on each packaged ray-traced city by name (training, imitation and the quickstart fly the
    map file above: the same code path, a map by path or by name)."""
    assert name in RADIO_MAPS
    [row] = rollout.main(rollout.Args(map=name, policy="replan", episodes=1))
    assert row["pr_pct"] == 100.0
    out = tmp_path / "f.csv"
    argv = ["--map", name, "--count", "1", "--settings", "2x6", "--jobs", "1", "--dispatchers", "greedy",
            "--out-csv", str(out)]  # fmt: skip
    assert fleet_benchmark.cli(argv) == 0
    [fleet] = _rows(out)
    assert (fleet["family"], fleet["setting"]) == (name, "2x6") and float(fleet["service_pct"]) == 100.0
    written = render.main(render.Args(map=name, policy="straight", out=tmp_path / f"{name}.html"))
    assert written["html"].is_file()
    printed = capsys.readouterr().out
    assert printed.count("Map: ") == 3 and f"on {name}:" in printed


@pytest.mark.slow
@pytest.mark.parametrize("name", RAY_TRACED_CITIES)
def test_every_packaged_city_trains_imitates_and_runs_the_quickstart(name: str, tmp_path: Path, capsys) -> None:
    """The learning commands on each packaged ray-traced city by name, at tiny budgets (the tests above check what
    they do with a map; here each city's own instances, thresholds and rasters go through them)."""
    from uamfleet.cli import imitate, quickstart, train

    threshold = map_family(name).thresholds_db[-1]
    argv = ["--scenario", "berlin_instances", "--map", name, "--total-timesteps", "64", "--num-envs", "4",
            "--num-steps", "16", "--eval-every", "1", "--curve-instances", "2", "--run-dir", str(tmp_path / "train"),
            "--threads", "1"]  # fmt: skip
    assert train.cli(argv) == 0
    [run] = list((tmp_path / "train").iterdir())
    [row] = _rows(run / "progress.csv")
    assert float(row["val_td_m"]) > 0
    argv = ["--map", name, "--envs-per-threshold", "1", "--rounds", "1", "--steps-per-round", "6",
            "--eval-instances", "2", "--epochs", "1", "--minibatch", "16", "--run-dir", str(tmp_path / "imitate"),
            "--run-name", "tiny"]  # fmt: skip
    assert imitate.cli(argv) == 0
    assert len(_rows(tmp_path / "imitate" / "tiny" / "progress.csv")) == 2
    argv = ["--map", name, "--total-timesteps", "2048", "--test-count", "2", "--run-dir", str(tmp_path / "quick")]
    assert quickstart.cli(argv) == 0
    out = capsys.readouterr().out
    assert out.count(f"Map: packaged map '{name}'") == 3
    assert f"on berlin_instances on {name} at {threshold:g} dB" in out
