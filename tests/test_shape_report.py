"""scripts/shape_report.py: McCabe complexity as radon counts it (hand-counted below), numba kernels left out,
function and module lengths, and the exit status the lead reads."""

from __future__ import annotations

import ast
import importlib.util
import sys
import textwrap
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "shape_report.py"


def _load():
    spec = importlib.util.spec_from_file_location("shape_report", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["shape_report"] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


shape = _load()

# Every decision point radon counts, once each; the hand count is in the comments (1 to start).
EVERY_DECISION = """
def f(a, b, xs):
    if a and b or a:  # if 1, "or" 1, "and" 1: 4
        pass
    elif b:  # 5
        pass
    for x in xs:  # loop 1 and its else 1: 7
        pass
    else:
        pass
    while a:  # 8
        break
    try:  # 2 handlers and the else: 11 (finally counts nothing)
        pass
    except ValueError:
        pass
    except KeyError:
        pass
    else:
        pass
    finally:
        pass
    ys = [x for x in xs if x if not x]  # the comprehension 1 and its 2 ifs: 14
    z = lambda v: 1 if v else 0  # the conditional expression inside the lambda: 15
    assert a and (b or a)  # the assert 1, nothing inside it: 16
    def inner(v):  # its own complexity (2), none of f's
        if v:
            return 1
    class K:
        def m(self):  # its own complexity (2), none of f's
            if self:
                pass
    match a:  # 3 cases, one the wildcard: 18
        case 1:
            pass
        case 2:
            pass
        case _:
            pass
    with open(a):  # nothing
        pass
    return ys, z
"""


def _functions(tmp_path: Path, source: str) -> dict[str, object]:
    path = tmp_path / "m.py"
    path.write_text(textwrap.dedent(source))
    return {f.qualname: f for f in shape.functions(path, "m.py")}


def test_complexity_counts_each_decision_as_radon_does(tmp_path: Path) -> None:
    found = _functions(tmp_path, EVERY_DECISION)
    assert {name: f.complexity for name, f in found.items()} == {"f": 18, "f.inner": 2, "f.K.m": 2}
    assert [name for name, f in found.items() if f.nested] == ["f.inner", "f.K.m"]
    assert found["f"].lines == len(EVERY_DECISION.strip().splitlines())


def test_a_straight_function_is_one() -> None:
    tree = ast.parse("def g(x):\n    y = x + 1\n    with open(x):\n        return y\n")
    assert shape.complexity(tree.body[0]) == 1


@pytest.mark.parametrize(
    ("decorator", "kernel"),
    [("@njit", True), ("@njit(cache=True)", True), ("@numba.njit(cache=True)", True), ("@nb.jit", True),
     ("@numba.vectorize", True), ("@functools.cache", False), ("@staticmethod", False)],
)  # fmt: skip
def test_numba_kernels_are_told_apart_by_their_decorator(tmp_path: Path, decorator: str, kernel: bool) -> None:
    found = _functions(tmp_path, f"{decorator}\ndef k(x):\n    return x\n")
    assert found["k"].kernel is kernel
    assert found["k"].lines == 2  # from the def, the decorator not counted


def _module(folder: Path, name: str, lines: int, body: str = "") -> None:
    text = body + "".join(f"x{i} = {i}\n" for i in range(lines - body.count("\n")))
    (folder / name).write_text(text)


def _long_function(name: str, lines: int, decorator: str = "") -> str:
    """A function of ``lines`` lines (complexity 1)."""
    return decorator + f"def {name}():\n" + "".join(f"    y{i} = {i}\n" for i in range(lines - 1))


def test_the_report_names_what_is_over_and_exits_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _module(tmp_path, "big.py", 601)
    _module(tmp_path, "fits.py", 600, _long_function("long", 61) + _long_function("fits", 60))
    kernel = _long_function("kernel", 80, "@njit\n") + "def branchy(a):\n" + "    if a:\n        pass\n" * 16
    _module(tmp_path, "kernels.py", 200, kernel)
    assert shape.main([str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "modules over 600 lines: 1\n" in out and f"  601  {tmp_path / 'big.py'}\n" in out
    assert "fits.py" not in out.split("functions over")[0]
    listed = out.split("(numba kernels left out): ")[1]
    assert listed.startswith("2\n")
    assert f"complexity  17  {tmp_path / 'kernels.py'}:82  branchy" in listed
    assert f"  61 lines  complexity   1  {tmp_path / 'fits.py'}:1  long" in listed
    assert "kernel\n" not in listed and "  fits\n" not in listed
    assert "(1 numba kernels)" in out


def test_the_report_exits_0_when_the_targets_hold(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _module(tmp_path, "fits.py", 600, _long_function("fits", 60))
    assert shape.main([str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "modules over 600 lines: 0\n" in out and out.endswith("(numba kernels left out): 0\n")
    assert shape.main([str(tmp_path), "--max-function-lines", "59"]) == 1


def test_a_missing_root_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert shape.main([str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert (
        err
        == f"shape_report.py: error: {tmp_path / 'nowhere'} does not exist; pass folders or .py files of the project.\n"
    )
