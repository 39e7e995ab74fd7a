"""Where the fleet dispatchers live and how their names are grouped: policies in ``uamfleet.baselines`` (none in a
command line module), every baselines module under 600 lines, and one definition of the dispatcher names that the
fleet benchmark's default and ``make_flown``'s option rules both read."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import uamfleet
from uamfleet.baselines import FLEET_DISPATCHERS, SCHEDULE_DISPATCHERS
from uamfleet.cli import fleet_benchmark
from uamfleet.policies import make_flown

PACKAGE = Path(uamfleet.__file__).resolve().parent


def test_the_fleet_benchmark_flies_every_dispatcher_that_needs_no_value_by_default():
    assert FLEET_DISPATCHERS == ("greedy", "insertion", "batch_assignment")
    assert fleet_benchmark.Args().dispatchers == FLEET_DISPATCHERS
    assert SCHEDULE_DISPATCHERS == ("insertion", "batch_assignment")


@pytest.mark.parametrize("name", FLEET_DISPATCHERS)
def test_options_belong_to_the_schedule_dispatchers_only(name):
    if name in SCHEDULE_DISPATCHERS:
        assert make_flown(f"{name}+wait=1", num_taxis=2).wait_weight == 1.0
    else:
        with pytest.raises(ValueError, match=rf"\+options belong to the schedule dispatchers, not to '{name}'"):
            make_flown(f"{name}+wait=1", num_taxis=2)


def _methods(node: ast.ClassDef) -> set[str]:
    return {item.name for item in node.body if isinstance(item, ast.FunctionDef)}


def test_no_command_line_module_defines_a_policy():
    """A class with ``reset`` and ``__call__`` (the policy's face, as run_episode drives it) belongs in a policy
    module (baselines, rl), where the benchmarks and tests import it without a command line."""
    policies = [
        f"{path.relative_to(PACKAGE.parent)}: {node.name}"
        for path in sorted((PACKAGE / "cli").rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.ClassDef) and {"reset", "__call__"} <= _methods(node)
    ]
    assert policies == []


def test_no_baselines_module_is_over_600_lines():
    sizes = {
        path.name: len(path.read_text(encoding="utf-8").splitlines()) for path in (PACKAGE / "baselines").glob("*.py")
    }
    assert {name: lines for name, lines in sizes.items() if lines > 600} == {}
