"""DAgger on several maps at once (``--map A --also-maps B ...``): each map's validation figures are those of a
one-map run on it, the run's metric is their mean, and bad map lists are refused naming the fix."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from uamfleet.config import ConfigError
from uamfleet.radio.packaged import RADIO_MAPS
from uamfleet.rl.imitation import ImitationArgs, imitate


def _start_row(tmp_path: Path, name: str, **options: object) -> dict[str, float]:
    """The untrained policy's validation row of a run that stops before its first round (``max_wall_s=0``)."""
    args = ImitationArgs.from_flat(dict(
        envs_per_threshold=1, eval_instances=2, max_wall_s=0.0, run_dir=tmp_path, run_name=name, **options,
    ))  # fmt: skip
    imitate(args)
    with open(tmp_path / name / "progress.csv", newline="") as f:
        [row] = list(csv.DictReader(f))
    return {k: float(v) for k, v in row.items()}


@pytest.mark.slow  # three runs that fill every threshold's path tables: 148 s on the loaded shared machine
def test_a_mixture_of_maps_validates_on_each_map_and_averages(tmp_path: Path) -> None:
    mixed = _start_row(tmp_path, "mixed", map="berlin", also_maps=("munich",))
    berlin = _start_row(tmp_path, "berlin", map="berlin")
    munich = _start_row(tmp_path, "munich", map="munich")
    # each map's figures are a one-map run's on the same validation seeds (an independent run per map)
    assert mixed["val_td_m@berlin"] == berlin["val_td_m"] and mixed["val_pr_pct@berlin"] == berlin["val_pr_pct"]
    assert mixed["val_td_m@munich"] == munich["val_td_m"] and mixed["val_pr_pct@munich"] == munich["val_pr_pct"]
    assert berlin["val_td_m"] != munich["val_td_m"]  # two different cities, so the mean below is a real mean
    assert mixed["val_td_m"] == pytest.approx((berlin["val_td_m"] + munich["val_td_m"]) / 2)
    assert mixed["val_pr_pct"] == pytest.approx((berlin["val_pr_pct"] + munich["val_pr_pct"]) / 2)
    assert "val_td_m@berlin" not in berlin  # a one-map run keeps its columns


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (dict(also_maps=("munich",)), r"--also-maps=\['munich'\] adds maps to --map's: pass --map too"),
        (dict(map="berlin", also_maps=("atlantis",)), "--also-maps='atlantis': no packaged map of that name"),
        (dict(map="berlin", also_maps=("munich", "berlin")), "name each map once"),
    ],
)
def test_bad_map_lists_are_refused_naming_the_fix(options: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        ImitationArgs.from_flat(options)


def test_an_unknown_map_is_refused_with_every_packaged_map_named() -> None:
    with pytest.raises(ConfigError) as err:
        ImitationArgs.from_flat(dict(map="atlantis"))
    assert all(name in str(err.value) for name in RADIO_MAPS)  # munich_3km too, from RADIO_MAPS


def test_the_command_prints_every_map_it_rolls_out_on(monkeypatch, capsys) -> None:
    from uamfleet.cli import imitate as imitate_cli
    from uamfleet.instances import map_provenance

    seen: list[ImitationArgs] = []

    def fake(args: ImitationArgs) -> dict[str, float]:  # the run itself is tested above
        seen.append(args)
        return {"round": 0, "val_pr_pct": 100.0, "val_td_m": 1.0}

    monkeypatch.setattr(imitate_cli, "imitate", fake)
    assert imitate_cli.cli(["--map", "berlin", "--also-maps", "munich", "munich_3km", "--run-name", "t"]) == 0
    assert [args.maps() for args in seen] == [("berlin", "munich", "munich_3km")]
    printed = capsys.readouterr().out.splitlines()
    assert printed[:3] == [f"Map: {map_provenance(name)}." for name in ("berlin", "munich", "munich_3km")]
