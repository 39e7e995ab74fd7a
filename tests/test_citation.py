"""The files at the top that say how the project may be used and cited: LICENSE is the MIT licence that
pyproject.toml declares, and CITATION.cff (Citation File Format 1.2.0) names this version of the package and the
MSHA-RL paper it reproduces."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
CITATION = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
# The paper's source, beside the repository (../shared) or in the shared folder of the machine, when present.
PAPER = next(
    (p for p in (ROOT.parent / "shared", Path("/work/shared")) if (p / "paper" / "msha_rl_paper.tex").is_file()), None
)


def top_level_scalars(text: str) -> dict[str, str]:
    """The ``key: value`` lines of a YAML file's top level (what this test needs when PyYAML is absent)."""
    found = re.findall(r"^([a-z][a-z-]*): *(.*)$", text, flags=re.MULTILINE)
    return {key: value.strip().strip('"') for key, value in found}


def citation() -> dict[str, Any]:
    try:
        import yaml
    except ImportError:
        return top_level_scalars(CITATION)
    return yaml.safe_load(CITATION)


def test_the_licence_is_mit_as_pyproject_declares() -> None:
    assert PROJECT["license"] == "MIT"
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License\n\nCopyright (c) 2026 ")
    # The body is word for word the one of the Berlin map's MIT licence, kept as it is.
    berlin = (ROOT / "uamfleet" / "data" / "LICENSE.berlin").read_text(encoding="utf-8")
    body = text[text.index("Permission is hereby granted") :]
    assert body == berlin[berlin.index("Permission is hereby granted") :]


def test_the_citation_names_this_package_and_version() -> None:
    cff = citation()
    assert cff["cff-version"] == "1.2.0"
    assert cff["version"] == PROJECT["version"] and cff["license"] == PROJECT["license"]
    assert cff["title"].startswith(f"{PROJECT['name']}: ")
    urls = PROJECT.get("urls", {})
    assert cff.get("repository-code") in (None, *urls.values())  # only a URL that pyproject names


def test_the_citation_references_the_msha_rl_paper() -> None:
    yaml = pytest.importorskip("yaml")
    (paper,) = yaml.safe_load(CITATION)["references"]
    assert paper["url"] == "https://arxiv.org/abs/2507.14249" and paper["doi"] == "10.48550/arXiv.2507.14249"
    if PAPER is None:
        pytest.skip("the paper's source (../shared/paper/msha_rl_paper.tex) is not on this machine")
    tex = (PAPER / "paper" / "msha_rl_paper.tex").read_text(encoding="utf-8")
    title = re.search(r"\\title\{(?:\\huge )?([^}]*)\}", tex)
    authors = re.search(r"\\author\{([^\n\\]*)", tex)
    assert title is not None and authors is not None
    assert " ".join(paper["title"].split()) == " ".join(title.group(1).split())
    names = [name.strip().removeprefix("and ") for name in authors.group(1).split(",")]
    assert [f"{a['given-names']} {a['family-names']}" for a in paper["authors"]] == names
