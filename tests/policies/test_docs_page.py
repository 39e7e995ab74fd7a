"""docs/policies.md: its table is the registry's, and its snippet runs as written."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

from uamfleet import policies
from uamfleet.policies.registry import markdown_table

PAGE = Path(__file__).resolve().parents[2] / "docs" / "policies.md"


def test_the_page_lists_every_registered_policy_with_its_options() -> None:
    text = PAGE.read_text(encoding="utf-8")
    assert markdown_table() in text, "docs/policies.md's table is stale: paste policies.registry.markdown_table()"
    listed = [line.split("`")[1] for line in markdown_table().splitlines()[2:]]
    assert listed == list(policies.available())


def test_the_pages_snippet_runs() -> None:
    snippet = PAGE.read_text(encoding="utf-8").split("```python\n")[1].split("```")[0]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(snippet, str(PAGE), "exec"), {})
    assert out.getvalue() == "replan {'beam': 16} 100 % delivered\n"


def test_the_protocol_snippet_flies_a_dispatcher_through_reset_and_act() -> None:
    snippet = PAGE.read_text(encoding="utf-8").split("```python\n")[2].split("```")[0]
    assert "dispatcher.reset(env.sim)" in snippet and "dispatcher.act(obs)" in snippet
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(snippet, str(PAGE), "exec"), {})
    assert out.getvalue() == "20 steps flown\n"
