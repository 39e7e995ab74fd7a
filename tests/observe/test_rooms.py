"""The rooms of the observation: ``uamfleet/observe`` holds the spec, the observer and its components, each module
under 600 lines; ``uamfleet/env`` holds only the faces. That ``observe`` imports no face (and ``sim`` no
observation) is tests/test_layers.py's rule."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2] / "uamfleet"
MAX_LINES = 600


def _modules(package: str) -> dict[str, int]:
    return {p.stem: len(p.read_text().splitlines()) for p in (ROOT / package).glob("*.py")}


def test_the_observe_package_holds_the_observation_each_module_under_600_lines() -> None:
    lines = _modules("observe")
    expected = {
        "__init__",
        "spec",
        "legacy",
        "observer",
        "basic",
        "stops",
        "moves",
        "tours",
        "lookahead",
        "window",
    }
    assert set(lines) == expected
    assert {name: n for name, n in lines.items() if n > MAX_LINES} == {}


def test_the_env_package_holds_only_the_faces() -> None:
    # The faces, the one interface of the vector backends (backends) and the Policy protocol the faces are flown by.
    assert set(_modules("env")) == {
        "__init__",
        "vector_env",
        "parallel_env",
        "mixture",
        "workers",
        "backends",
        "protocol",
    }
