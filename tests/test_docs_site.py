"""The documentation site's page tree (``mkdocs.yml``): every page under ``docs/`` is in the nav, every page the
nav names exists, and CI builds the site with ``--strict`` after the tests."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import pytest

from tests.test_docs import TEST_COMMAND

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def nav_pages(node: Any) -> list[str]:
    """The page paths of a MkDocs nav: the strings at its leaves, in order (a section is a one-key mapping of a title
    to a list; a page is a path, or a one-key mapping of a title to a path)."""
    if isinstance(node, str):
        return [node]
    if isinstance(node, list):
        return [page for item in node for page in nav_pages(item)]
    if isinstance(node, dict):
        return [page for value in node.values() for page in nav_pages(value)]
    raise TypeError(f"mkdocs.yml: a nav entry {node!r} is neither a page, a list nor a titled entry")


def site_config() -> dict[str, Any]:
    # PyYAML comes with mkdocs (the `docs` extra that scripts/setup.sh installs).
    yaml = pytest.importorskip("yaml", reason="PyYAML is missing: install the docs extra (bash scripts/setup.sh)")
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    assert isinstance(config, dict), "mkdocs.yml does not hold a mapping"
    return config


def test_every_page_under_docs_is_in_the_nav() -> None:
    config = site_config()
    assert config.get("docs_dir", "docs") == "docs"
    pages = nav_pages(config["nav"])
    on_disk = sorted(path.relative_to(DOCS).as_posix() for path in DOCS.rglob("*.md"))
    missing = [page for page in on_disk if page not in pages]
    assert not missing, f"pages under docs/ that mkdocs.yml's nav does not list (add each to the nav): {missing}"
    absent = [page for page in pages if not (DOCS / page).is_file()]
    assert not absent, f"pages in mkdocs.yml's nav with no file under docs/: {absent}"
    repeated = sorted({page for page in pages if pages.count(page) > 1})
    assert not repeated, f"pages listed twice in mkdocs.yml's nav: {repeated}"


def test_ci_builds_the_site_strictly_after_the_tests() -> None:
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()]
    tests = lines.index(TEST_COMMAND)  # the README's
    builds = [i for i, line in enumerate(lines) if "mkdocs build --strict" in line and not line.startswith("#")]
    assert builds and builds[0] > tests, ".ci/run must run `mkdocs build --strict` after the test command"


def test_the_api_pages_show_sphinx_roles_as_inline_code() -> None:
    pytest.importorskip("griffe", reason="griffe is missing: install the docs extra (bash scripts/setup.sh)")
    spec = importlib.util.spec_from_file_location("sphinx_roles", DOCS / "_griffe" / "sphinx_roles.py")
    assert spec is not None and spec.loader is not None
    roles = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(roles)
    text = "See :func:`uamfleet.parallel_env`, :class:`~uamfleet.config.EnvConfig` and :py:meth:`RadioMap.sinr_at`."
    assert roles.plain(text) == "See `uamfleet.parallel_env`, `EnvConfig` and `RadioMap.sinr_at`."
    assert roles.plain("no role, ``code`` and :term: stay") == "no role, ``code`` and :term: stay"
