"""The shape figures of the project's size targets, in one command:

    .venv/bin/python scripts/shape_report.py            # uamfleet/
    .venv/bin/python scripts/shape_report.py uamfleet eval train benchmarks

Prints the modules over 600 lines and the functions over 60 lines or over complexity 15, numba kernels
(``@njit`` / ``@jit`` / ``@numba.*``) left out, and exits 1 when any is over (0 when the targets hold).

A module's lines are its newline count (``wc -l``). A function's lines are ``end_lineno - lineno + 1`` of its
``def`` (decorators not counted). Its complexity is McCabe's as radon computes it (``radon cc``), read from the
syntax tree here so that radon need not be installed: 1, plus 1 for each ``if``, ``elif``, conditional expression,
loop (and its ``else``), ``except`` handler (and a ``try``'s ``else``), ``assert``, comprehension ``for`` and its
``if``s, each extra operand of ``and`` / ``or``, and each ``case`` of a ``match`` but the wildcard; the bodies of
nested functions and classes count for themselves, never for the function around them. (Ruff's C901 counts
fewer: no boolean operators, comprehensions, conditional expressions or asserts, so it passes functions that radon
counts over 15.)

``--radon`` also computes each function's complexity with radon, when it is importable, and lists every function
where the two differ. radon is no dependency of the project; to get it beside the project's interpreter:

    python3 -m venv /tmp/radonvenv && /tmp/radonvenv/bin/pip install radon
    PYTHONPATH=/tmp/radonvenv/lib/python3.11/site-packages .venv/bin/python scripts/shape_report.py --radon
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60
MAX_COMPLEXITY = 15
KERNEL_DECORATORS = frozenset({"njit", "jit", "vectorize", "guvectorize", "cfunc", "stencil", "generated_jit"})
"""Decorator names (bare or the last part of a dotted name, called or not) that mark a numba kernel."""

_FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)


@dataclass(frozen=True)
class Function:
    path: str
    qualname: str  # Class.method, or outer.inner for a nested function
    lineno: int
    lines: int
    complexity: int
    kernel: bool
    nested: bool  # inside another function (radon reports these only as closures)

    def over(self, max_lines: int, max_complexity: int) -> bool:
        return not self.kernel and (self.lines > max_lines or self.complexity > max_complexity)


def complexity(function: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """McCabe complexity of ``function`` as radon counts it (module docstring)."""
    return 1 + sum(_decisions(statement) for statement in function.body)


def _decisions(node: ast.AST) -> int:
    """Decision points in ``node`` and under it, nested functions and classes left out."""
    if isinstance(node, (*_FUNCTIONS, ast.ClassDef)):
        return 0
    if isinstance(node, ast.Assert):  # radon counts the assert and does not look inside it
        return 1
    return _own_decisions(node) + sum(_decisions(child) for child in ast.iter_child_nodes(node))


def _own_decisions(node: ast.AST) -> int:
    """Decision points of ``node`` itself."""
    if isinstance(node, ast.Try):
        return len(node.handlers) + bool(node.orelse)
    if isinstance(node, ast.BoolOp):
        return len(node.values) - 1
    if isinstance(node, (ast.If, ast.IfExp)):
        return 1
    if isinstance(node, ast.Match):
        wildcard = any(isinstance(case.pattern, ast.MatchAs) and case.pattern.pattern is None for case in node.cases)
        return max(0, len(node.cases) - wildcard)
    if isinstance(node, (ast.For, ast.AsyncFor, ast.While)):
        return 1 + bool(node.orelse)
    if isinstance(node, ast.comprehension):
        return 1 + len(node.ifs)
    return 0


def is_kernel(function: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Whether a decorator of ``function`` compiles it with numba."""
    for decorator in function.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        dotted = ast.unparse(target)
        if dotted.split(".")[-1] in KERNEL_DECORATORS or dotted.split(".")[0] == "numba":
            return True
    return False


def functions(path: Path, shown: str) -> Iterator[Function]:
    """Every function and method of the module at ``path`` (``shown`` as its name), nested ones included."""
    yield from _walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)), shown, "", False)


def _walk(node: ast.AST, path: str, prefix: str, in_function: bool) -> Iterator[Function]:
    for child in ast.iter_child_nodes(node):
        if isinstance(child, _FUNCTIONS):
            name = prefix + child.name
            lines = (child.end_lineno or child.lineno) - child.lineno + 1
            yield Function(path, name, child.lineno, lines, complexity(child), is_kernel(child), in_function)
            yield from _walk(child, path, name + ".", True)
        elif isinstance(child, ast.ClassDef):
            yield from _walk(child, path, prefix + child.name + ".", in_function)
        else:
            yield from _walk(child, path, prefix, in_function)


def modules(roots: list[Path]) -> list[Path]:
    """The Python files under ``roots`` (files or folders), sorted; caches left out."""
    found: list[Path] = []
    for root in roots:
        if not root.exists():
            raise FileNotFoundError(f"{root} does not exist; pass folders or .py files of the project.")
        found += [root] if root.is_file() else [p for p in root.rglob("*.py") if "__pycache__" not in p.parts]
    return sorted(found)


def radon_differences(paths: list[Path], found: list[Function]) -> list[str]:
    """Each function radon lists whose complexity differs from ours (radon's blocks: functions and methods)."""
    from radon.complexity import cc_visit

    ours = {(f.path, f.lineno): f for f in found if not f.nested}
    differences = []
    for path in paths:
        for block in cc_visit(path.read_text(encoding="utf-8")):
            if not hasattr(block, "is_method"):  # a class: the sum of its methods, no target of its own
                continue
            mine = ours.get((str(path), block.lineno))
            if mine is None or mine.complexity != block.complexity:
                figure = "missing" if mine is None else mine.complexity
                differences.append(f"{path}:{block.lineno} {block.fullname}: radon {block.complexity}, here {figure}")
    return differences


def report(roots: list[Path], max_module: int, max_lines: int, max_complexity: int, radon: bool) -> int:
    """Print the figures; 1 when a module or function is over its target, else 0."""
    paths = modules(roots)
    long_modules = [(p, p.read_bytes().count(b"\n")) for p in paths]
    long_modules = [(p, n) for p, n in long_modules if n > max_module]
    found = [f for p in paths for f in functions(p, str(p))]
    over = sorted((f for f in found if f.over(max_lines, max_complexity)), key=lambda f: (-f.complexity, -f.lines))
    kernels = sum(f.kernel for f in found)
    print(
        f"shape of {', '.join(map(str, roots))}: {len(paths)} modules, {len(found)} functions ({kernels} numba kernels)"
    )
    print(f"modules over {max_module} lines: {len(long_modules)}")
    for path, count in sorted(long_modules, key=lambda item: -item[1]):
        print(f"  {count:5d}  {path}")
    print(f"functions over {max_lines} lines or complexity {max_complexity} (numba kernels left out): {len(over)}")
    for f in over:
        print(f"  {f.lines:4d} lines  complexity {f.complexity:3d}  {f.path}:{f.lineno}  {f.qualname}")
    if radon:
        _print_radon_check(paths, found)
    return 1 if long_modules or over else 0


def _print_radon_check(paths: list[Path], found: list[Function]) -> None:
    try:
        differences = radon_differences(paths, found)
    except ImportError:
        print("radon is not importable: see this script's docstring for how to get it (no project dependency).")
        return
    print(f"radon's complexity differs for {len(differences)} functions")
    for line in differences:
        print("  " + line)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="shape_report.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("roots", nargs="*", type=Path, default=[Path("uamfleet")], help="folders or .py files")
    parser.add_argument("--max-module-lines", type=int, default=MAX_MODULE_LINES)
    parser.add_argument("--max-function-lines", type=int, default=MAX_FUNCTION_LINES)
    parser.add_argument("--max-complexity", type=int, default=MAX_COMPLEXITY)
    parser.add_argument("--radon", action="store_true", help="check each function's complexity against radon's")
    args = parser.parse_args(argv)
    try:
        return report(args.roots, args.max_module_lines, args.max_function_lines, args.max_complexity, args.radon)
    except (FileNotFoundError, SyntaxError) as err:
        print(f"shape_report.py: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
