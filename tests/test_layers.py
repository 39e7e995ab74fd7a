"""Imports point one way: radio -> paths -> sim -> env -> {baselines, rl} -> rollout/metrics -> viz -> CLIs.

Every module of ``uamfleet/``, ``eval/``, ``train/`` and ``benchmarks/`` is parsed (``ast``, so imports inside
functions count too) and each import of a project module becomes an edge. An edge may point down or sideways
inside one layer, never up; the graph may hold no circle. Run it alone with::

    .venv/bin/python -m pytest -q tests/test_layers.py

Allowed on purpose (and only these):

- imports under ``if TYPE_CHECKING:`` are annotations, never executed, and are not edges;
- ``uamfleet/__init__.py`` is the public face (``uamfleet.parallel_env``, ``uamfleet.vector_env``, ...): it is
  the top of the package and may import any layer; nothing in the package may import it;
- a ``from pkg import name`` also runs ``pkg/__init__.py``: that package is an edge too, unless the importer
  lives inside it (a package's own modules run their ``__init__`` anyway).
"""

from __future__ import annotations

import ast
import itertools
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("uamfleet", "eval", "train", "benchmarks")

# Layer of each module by longest matching prefix; a module may import its own layer or lower ones.
# config, types and io are the base every layer may use (config reads radio maps, so it sits just above radio).
LAYERS: tuple[tuple[int, tuple[str, ...]], ...] = (
    # uamfleet.checks: ConfigError, the check_* helpers and the size bounds; uamfleet.demand: the requests and the
    # demand model, parts of the config (which re-exports both).
    (0, ("uamfleet.types", "uamfleet.io", "uamfleet.checks")),
    (1, ("uamfleet.radio",)),
    # uamfleet.presets: the named scenarios (make_config), built from the config classes beside them.
    # uamfleet.map_rules: Berlin's instance rules scaled to a map (its steps and thresholds), read from presets.
    (2, ("uamfleet.config", "uamfleet.demand", "uamfleet.presets", "uamfleet.map_rules")),
    (3, ("uamfleet.paths",)),
    # The simulator (world, rules, motion, reward) reads no observation; the observers and faces sit above it.
    (4, ("uamfleet.sim",)),
    # What a policy reads: the observation's spec, the observer, its kernels and the tour planner they read.
    (5, ("uamfleet.observe",)),
    # The faces: the simulator with its observer (vector env, PettingZoo env, mixture, workers).
    (6, ("uamfleet.env",)),
    # The held-out instances (and their batched validation) are drawn from env and paths; rl's trainer uses them.
    # Below the loop in rl: the training options (rl.options), checkpoints (rl.checkpoint) and the run folder and
    # its log (rl.runs), so reading a checkpoint or a run's progress never imports the loop.
    # rl.legacy (format-1 files, the flat training arguments) sits beside rl.checkpoint, whose Checkpoint it reads.
    (7, ("uamfleet.baselines", "uamfleet.rl", "uamfleet.rl.checkpoint", "uamfleet.rl.legacy", "uamfleet.instances")),
    (8, ("uamfleet.rollout", "uamfleet.metrics")),
    # The training loop evaluates its greedy policy with rollout + metrics: it sits above them, below viz.
    # So does the greedy policy (GreedyPolicy.fly, load_policy), which the loop evaluates and the zoo ships (the
    # zoo imports the policy room, never the loop: test_loading_a_shipped_policy_does_not_import_the_trainer);
    # imitation learning labels with the baselines' step-level search (its experts, rl.experts), and guided search
    # rolls the greedy policy forward. The learner (rl.learner) starts an --init-from run from a policy it loads
    # with load_policy; the collector (rl.collector) needs no policy room and stays below, with the rest of rl.
    (
        9,
        (
            "uamfleet.rl.trainer",
            "uamfleet.rl.learner",
            "uamfleet.rl.warm_start",  # the search warm start: the experts' labels into the learner's network
            "uamfleet.rl.policy",
            "uamfleet.rl.imitation",
            "uamfleet.rl.fleet_imitation",  # DAgger from a fleet dispatcher: the learned policies' loader, rollout
            "uamfleet.rl.fleet_claims",  # a fleet policy reading a dispatcher's claims: the greedy policy, a dispatcher
            "uamfleet.rl.fleet_finetune",  # the claims policy fine-tuned with the return: fleet_imitation's episodes
            "uamfleet.rl.expert_iteration",
            "uamfleet.rl.experts",
            "uamfleet.rl.guided",
            "uamfleet.rl.labels",
            "uamfleet.zoo",
            "uamfleet.policies",
        ),
    ),
    (10, ("uamfleet.viz",)),
    (11, ("uamfleet",)),  # the public face, uamfleet/__init__.py
    # The command lines: their implementations in uamfleet.cli (installed as console scripts), thin wrappers in
    # eval/ and train/.
    # uamfleet/__main__.py is ``python -m uamfleet``, the ``uamfleet`` command: a command line too.
    (12, ("uamfleet.cli", "uamfleet.__main__", "eval", "train", "benchmarks")),
)
# Packages of one layer that must not import each other (siblings, not a stack).
SIBLINGS = ("uamfleet.baselines", "uamfleet.rl")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    files = [p for src in SOURCES for p in (ROOT / src).rglob("*.py") if ".venv" not in p.parts]
    return {module_name(p): p for p in sorted(files)}


def is_package(name: str, modules: dict[str, Path]) -> bool:
    return modules[name].name == "__init__.py"


def type_checking_only(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imported_names(
    tree: ast.AST, importer: str, importer_is_package: bool, annotations: bool = False
) -> list[tuple[str, int]]:
    """(absolute dotted name, line) of every import outside ``if TYPE_CHECKING:`` blocks (inside them too with
    ``annotations``); ``from a import b`` gives ``a.b`` (a module or a name in ``a``, resolved by the caller)."""
    out: list[tuple[str, int]] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and type_checking_only(node) and not annotations:
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            out.extend((alias.name, node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = importer.split(".") if importer_is_package else importer.split(".")[:-1]
                package = package[: len(package) - (node.level - 1)]
                base = ".".join([*package, base] if base else package)
            out.extend((f"{base}.{alias.name}", node.lineno) for alias in node.names)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return out


def edges(modules: dict[str, Path], annotations: bool = False) -> dict[str, dict[str, int]]:
    """importer -> {imported project module: line} (with ``annotations``, the imports for type checking too)."""
    graph: dict[str, dict[str, int]] = {}
    for name, path in modules.items():
        targets: dict[str, int] = {}
        tree = ast.parse(path.read_text(), str(path))
        for dotted, line in imported_names(tree, name, is_package(name, modules), annotations):
            parts = dotted.split(".")
            # the longest prefix that is a project module (``from m import f`` -> m; ``from pkg import mod`` -> mod)
            prefixes = (".".join(parts[:i]) for i in range(len(parts), 0, -1))
            found = next((p for p in prefixes if p in modules), None)
            if found is None or found == name:
                continue
            chain = found.split(".")
            for i in range(1, len(chain) + 1):  # the packages whose __init__ the import runs
                target = ".".join(chain[:i])
                if target == name:
                    continue
                if target == found or (is_package(target, modules) and not name.startswith(target + ".")):
                    if target == "uamfleet" and found != "uamfleet":
                        continue  # every uamfleet.x import runs the face's __init__; only an explicit one counts
                    targets.setdefault(target, line)
        graph[name] = targets
    return graph


def layer(name: str) -> tuple[int, str]:
    best = max(
        ((rank, prefix) for rank, prefixes in LAYERS for prefix in prefixes
         if name == prefix or name.startswith(prefix + ".")),
        key=lambda rp: len(rp[1]),
        default=None,
    )  # fmt: skip
    if best is None:
        raise AssertionError(f"module {name} is in no layer: add its prefix to LAYERS in tests/test_layers.py")
    return best


MODULES = all_modules()
GRAPH = edges(MODULES)


def test_every_module_has_a_layer_and_the_walk_sees_the_known_edges() -> None:
    for name in MODULES:
        layer(name)
    # the walk must find imports inside functions and through packages, or the other tests prove nothing
    assert "uamfleet.env.vector_env" in GRAPH["uamfleet.rollout"]
    assert "uamfleet.viz.figures" in GRAPH["uamfleet.viz.strip"]  # imported inside plot_sinr_strip
    assert "uamfleet.viz.render" in GRAPH["uamfleet"]  # imported inside the face's renderer factory
    assert "uamfleet.rollout" not in GRAPH["uamfleet.viz.meshcat_view"]  # only under TYPE_CHECKING
    assert "uamfleet.paths" in GRAPH["uamfleet.sim.reward"]  # the shaping potential's distance table
    assert "uamfleet.radio" in GRAPH["uamfleet.config"]
    assert "uamfleet.config" in GRAPH["uamfleet.presets"]  # sideways, inside layer 2
    assert len(MODULES) > 40 and sum(map(len, GRAPH.values())) > 100


def test_no_import_points_up() -> None:
    upward = []
    for importer, targets in GRAPH.items():
        rank, prefix = layer(importer)
        for target, line in targets.items():
            target_rank, target_prefix = layer(target)
            sibling = target_rank == rank and target_prefix != prefix and {prefix, target_prefix} <= set(SIBLINGS)
            if target_rank > rank or sibling:
                upward.append(f"{MODULES[importer].relative_to(ROOT)}:{line}: {importer} (layer {prefix}) imports "
                              f"{target} (layer {target_prefix})")  # fmt: skip
    assert not upward, "imports that point up or across sibling layers:\n" + "\n".join(upward)


def find_cycle(graph: dict[str, dict[str, int]]) -> list[str] | None:
    state: dict[str, int] = {}  # 1 = on the stack, 2 = done
    stack: list[str] = []

    def dfs(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, {})):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (cycle := dfs(nxt)) is not None:
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := dfs(node)) is not None:
            return cycle
    return None


def test_no_import_circle() -> None:
    cycle = find_cycle(GRAPH)
    assert cycle is None, "import circle: " + ", ".join(
        f"{a} imports {b} ({MODULES[a].relative_to(ROOT)}:{GRAPH[a][b]})" for a, b in itertools.pairwise(cycle)
    )


def test_no_circle_even_through_type_annotations() -> None:
    """A module that imports another only for its types still depends on it (the kernels read the world's
    arrays): no circle through ``if TYPE_CHECKING:`` imports either, e.g. kernels <-> world."""
    graph = edges(MODULES, annotations=True)
    assert "uamfleet.rollout" in graph["uamfleet.viz.meshcat_view"]  # the walk sees annotation imports
    cycle = find_cycle(graph)
    assert cycle is None, "import circle through type annotations: " + ", ".join(
        f"{a} imports {b} ({MODULES[a].relative_to(ROOT)}:{graph[a][b]})" for a, b in itertools.pairwise(cycle)
    )


@pytest.mark.parametrize(
    ("graph", "expected"),
    [({"a": {"b": 1}, "b": {"c": 1}, "c": {"a": 1}}, ["a", "b", "c", "a"]), ({"a": {"b": 1}, "b": {}}, None)],
)
def test_the_cycle_finder_finds_a_drawn_circle(graph: dict[str, dict[str, int]], expected: list[str] | None) -> None:
    assert find_cycle(graph) == expected


def reachable(graph: dict[str, dict[str, int]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        node = todo.pop()
        if node not in seen:
            seen.add(node)
            todo.extend(graph.get(node, {}))
    return seen


def test_loading_a_shipped_policy_does_not_import_the_trainer() -> None:
    """uamfleet.pretrained() goes through the zoo and the policy room (load_policy), never the training loop:
    neither by any import the walk sees nor at run time."""
    assert "uamfleet.rl.policy" in reachable(GRAPH, "uamfleet.zoo")  # the walk reaches the loader
    assert "uamfleet.rl.trainer" not in reachable(GRAPH, "uamfleet.zoo")
    probe = "import sys, uamfleet, uamfleet.zoo; print('uamfleet.rl.trainer' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "False"


def test_the_training_rooms_take_the_shipped_files_from_the_checkpoint_room_and_stand_apart() -> None:
    """Nothing in uamfleet.rl imports the zoo (the public face that loads shipped policies sits on rl, never under
    it: rl takes PRETRAINED and pretrained_path from rl.checkpoint, where they are defined). The stop head
    (rl.heads) is built from the encoders without the torso's module, and the experts that label DAgger's states
    (rl.experts) search with the baselines without the imitation loop or the trainer."""
    assert "uamfleet.rl.checkpoint" in reachable(GRAPH, "uamfleet.zoo")  # the walk reaches the definitions
    assert [name for name in GRAPH if name.startswith("uamfleet.rl.") and "uamfleet.zoo" in GRAPH[name]] == []
    assert "uamfleet.rl.checkpoint" in GRAPH["uamfleet.rl.imitation"]
    assert "uamfleet.rl.encoders" in GRAPH["uamfleet.rl.heads"]
    assert "uamfleet.rl.networks" not in reachable(GRAPH, "uamfleet.rl.heads")
    assert "uamfleet.baselines.step_planner" in GRAPH["uamfleet.rl.experts"]
    assert not {"uamfleet.rl.imitation", "uamfleet.rl.trainer"} & reachable(GRAPH, "uamfleet.rl.experts")


def test_the_collector_stands_below_the_learner_and_the_loop() -> None:
    """The collector (rl.collector: the run's envs and buffer, collect_rollout) is given the acting network; it
    imports neither the learner (optimiser, PPO update) nor the loop, which both build on it."""
    assert "uamfleet.rl.buffer" in GRAPH["uamfleet.rl.collector"]  # the walk sees the collector's imports
    assert "uamfleet.rl.collector" in GRAPH["uamfleet.rl.learner"]
    assert {"uamfleet.rl.collector", "uamfleet.rl.learner"} <= set(GRAPH["uamfleet.rl.trainer"])
    assert not {"uamfleet.rl.learner", "uamfleet.rl.trainer"} & reachable(GRAPH, "uamfleet.rl.collector")
