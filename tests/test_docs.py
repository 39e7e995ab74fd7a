"""Every code block of the README and the documentation site runs as written, sized by a comment above it.

The pages are ``README.md`` and every ``docs/**/*.md``. Two kinds of fenced block run:

- ```` ```python ```` blocks: the blocks of one page run in order in one namespace (so a later block uses the
  names of an earlier one), in a fresh temporary folder as the current folder (so the files a snippet writes land
  there), with the project's root importable. One test per page: ``test_python_blocks_run[<page>]``.
- ```` ```bash ```` blocks: each command line of a block that starts with ``uamfleet `` or ``python -m `` (after
  any ``NAME=value`` environment assignments, such as ``OMP_NUM_THREADS=1``, which it runs with) runs through
  :mod:`subprocess` (``uamfleet X`` as ``python -m uamfleet X``, ``python`` as this interpreter) and must exit 0;
  other lines (``bash scripts/setup.sh``, ``.venv/bin/torchrun``, ``source ...``) are not run (CI runs
  the set-up). Lines continued with ``\\`` are one command; ``#`` starts a comment. The blocks of one page run in
  order in one temporary folder (a later command reads what an earlier one wrote), with the project's root on
  ``PYTHONPATH`` and its ``uamfleet/data`` linked there (so a command names a shipped file, such as
  ``uamfleet/data/pretrained/berlin.pt``, by its path in a checkout). One test per page:
  ``test_bash_blocks_run[<page>]``.

**The comment above a block.** An HTML comment ``<!-- test: ... -->`` on the line before the fence says how the
block is tested; a bash block with a command to run must have one, so that no page documents a command of hours
that the suite would run as written (``<!-- test: -->`` runs it as written). Its words, in any order:

- ``slow``: the block runs only in the page's second test, ``[<page>:slow]``, marked ``slow`` (run with
  ``pytest -m slow``), which runs all the page's blocks in order; for a block over about 20 s;
- ``apart``: the block reads nothing that an earlier block of its page wrote, so it runs in a test of its own,
  ``[<page>:<line>]``, in a fresh folder: the two workers of the README's ``pytest -n 2`` then share a long page
  (docs/results.md's blocks took 99 s as one test). A block that did read an earlier one's file fails there;
- ``needs:MODULE``: the page's tests are skipped when ``MODULE`` is not importable (``needs:sionna`` for ray tracing);
- ``engines`` (python blocks): the block runs alone in the engines venv (``bash scripts/engines.sh --setup``,
  ``$UAMFLEET_ENGINES_VENV`` or ``~/.cache/uamfleet-engines/venv``) as a script from a temporary folder with the
  project's root on ``PYTHONPATH``, in ``test_engine_blocks_run`` (``slow``; skipped when that venv is absent), and
  not in the page's namespace;
- ``skip:REASON`` (one word or more, to the end of the comment): the block does not run; the reason is required;
- anything else is arguments for the block's commands (bash): an option given there (``--name`` and the values
  after it, up to the next ``--option``) replaces the same option's values on every command line of the block that
  has it, and is appended to the lines that do not. So ``<!-- test: --total-timesteps 512 -->`` above
  ``uamfleet train --total-timesteps 3000000`` runs ``uamfleet train --total-timesteps 512``: the documented
  command and the tested one differ only in size.

Beside the blocks: the README stays at most 150 lines, its quick start's expected output is the landing page's
and the getting-started page's, letter for letter, and ``docs/layout.md``'s layer table is ``tests/test_layers.py``'s
``LAYERS``.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.test_layers import LAYERS

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```(\S*)\s*$")
DIRECTIVE = re.compile(r"^<!--\s*test:(.*?)-->\s*$")
RUNNABLE = ("uamfleet ", "python -m ")
ASSIGNMENTS = re.compile(r"^(?:[A-Za-z_][A-Za-z0-9_]*=\S*\s+)*")  # NAME=value words before a command
CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
ENGINES_VENV = Path(os.environ.get("UAMFLEET_ENGINES_VENV", CACHE / "uamfleet-engines" / "venv"))
TIMEOUT_S = 600


@dataclass
class Directive:
    """What the ``<!-- test: ... -->`` comment above a block says (see the module's docstring)."""

    slow: bool = False
    apart: bool = False
    engines: bool = False
    skip: str | None = None
    needs: list[str] = field(default_factory=list)
    args: list[str] = field(default_factory=list)


@dataclass
class Block:
    page: Path
    line: int  # of the opening fence, 1-based
    lang: str
    code: str
    directive: Directive | None

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def parse_directive(text: str, where: str) -> Directive:
    directive = Directive()
    if "skip:" in text:
        text, reason = text.split("skip:", 1)
        if not reason.strip():
            raise AssertionError(f"{where}: `skip:` needs a reason after it, e.g. <!-- test: skip: needs a GPU -->")
        directive.skip = reason.strip()
    for word in shlex.split(text):
        if word == "slow":
            directive.slow = True
        elif word == "apart":
            directive.apart = True
        elif word == "engines":
            directive.engines = True
        elif word.startswith("needs:"):
            directive.needs.append(word.removeprefix("needs:"))
        else:
            directive.args.append(word)
    return directive


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a page, each with the directive on the line before its fence (if any)."""
    out: list[Block] = []
    lines = page.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        opening = FENCE.match(lines[i])
        if not opening:
            i += 1
            continue
        start, lang = i, opening[1]
        i += 1
        while i < len(lines) and lines[i].rstrip() != "```":
            i += 1
        if i == len(lines):
            raise AssertionError(f"{page.relative_to(ROOT)}:{start + 1}: a code block is never closed")
        where = f"{page.relative_to(ROOT)}:{start + 1}"
        above = DIRECTIVE.match(lines[start - 1]) if start else None
        directive = parse_directive(above[1], where) if above else None
        out.append(Block(page, start + 1, lang, "\n".join(lines[start + 1 : i]) + "\n", directive))
        i += 1
    return out


def commands(code: str) -> list[str]:
    """The command lines of a shell block that the test runs (continuations joined, comments dropped)."""
    joined = re.sub(r"\s*\\\n\s*", " ", code)
    out = []
    for line in joined.splitlines():
        line = line.split(" #", 1)[0].strip() if not line.lstrip().startswith("#") else ""
        if line[ASSIGNMENTS.match(line).end() :].startswith(RUNNABLE):  # type: ignore[union-attr]
            out.append(line)
    return out


def options(words: list[str]) -> list[tuple[str, list[str]]]:
    """``--name value ...`` groups of a directive's arguments, in order."""
    groups: list[tuple[str, list[str]]] = []
    for word in words:
        if word.startswith("--"):
            groups.append((word, []))
        elif groups:
            groups[-1][1].append(word)
        else:
            raise AssertionError(f"a test argument {word!r} comes before any --option")
    return groups


def sized(command: str, args: list[str]) -> list[str]:
    """``command`` as argv with the directive's options replacing or appended (see the module's docstring)."""
    argv = shlex.split(command)
    for name, values in options(args):
        if name in argv:
            at = argv.index(name)
            end = at + 1
            while end < len(argv) and not argv[end].startswith("--"):
                end += 1
            argv[at:end] = [name, *values]
        else:
            argv += [name, *values]
    return argv


def assignments(argv: list[str]) -> tuple[dict[str, str], list[str]]:
    """The ``NAME=value`` words that start ``argv``, as environment variables, and the command after them."""
    at = 0
    while at < len(argv) and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=.*", argv[at]):
        at += 1
    return dict(word.split("=", 1) for word in argv[:at]), argv[at:]


def interpreter_argv(argv: list[str], python: str = sys.executable) -> list[str]:
    """``uamfleet X`` -> ``python -m uamfleet X``; ``python ...`` -> this interpreter."""
    if argv[0] == "uamfleet":
        return [python, "-m", "uamfleet", *argv[1:]]
    assert argv[0] == "python", argv
    return [python, *argv[1:]]


def child_env() -> dict[str, str]:
    """The environment of a documented command: the project's root first on the path, so ``python -m eval.<name>``
    and ``uamfleet`` import this checkout whatever the current folder."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    return env


ALL = [block for page in PAGES for block in blocks(page)]


def is_slow(block: Block) -> bool:
    return bool(block.directive and block.directive.slow)


def is_apart(block: Block) -> bool:
    return bool(block.directive and block.directive.apart)


def params(lang: str) -> list:
    """The page tests of ``lang``: per page, its blocks that are neither ``slow`` nor ``apart`` (id: the page), each
    ``apart`` block that is not ``slow`` alone (id: ``<page>:<line>``), and, when it has ``slow`` blocks, all its
    blocks in order (id: ``<page>:slow``, marked ``slow``), so that a slow block may read what an earlier block of
    its page wrote."""
    out = []
    for page in PAGES:
        mine = [b for b in ALL if b.page == page and b.lang == lang and not (b.directive and b.directive.engines)]
        if lang == "bash":
            mine = [b for b in mine if commands(b.code)]
        page_id = str(page.relative_to(ROOT))
        quick = [b for b in mine if not is_slow(b)]
        if any(not is_apart(b) for b in quick):
            out.append(pytest.param([b for b in quick if not is_apart(b)], id=page_id))
        out += [pytest.param([b], id=f"{page_id}:{b.line}") for b in quick if is_apart(b)]
        if any(is_slow(b) for b in mine):
            out.append(pytest.param(mine, id=f"{page_id}:slow", marks=pytest.mark.slow))
    return out


def needs(page_blocks: list[Block]) -> None:
    for block in page_blocks:
        for module in block.directive.needs if block.directive else []:
            pytest.importorskip(module, reason=f"{block.where} needs {module}, which this venv lacks")


@pytest.mark.parametrize("page_blocks", params("python"))
def test_python_blocks_run(page_blocks: list[Block], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    needs(page_blocks)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(ROOT))
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for block in page_blocks:
        if block.directive and block.directive.skip:
            continue
        exec(compile(block.code, block.where, "exec"), namespace)  # the page's own snippet


@pytest.mark.parametrize("page_blocks", params("bash"))
def test_bash_blocks_run(page_blocks: list[Block], tmp_path: Path) -> None:
    needs(page_blocks)
    (tmp_path / "uamfleet").mkdir()  # no __init__.py: ``import uamfleet`` still finds the project's package
    (tmp_path / "uamfleet" / "data").symlink_to(ROOT / "uamfleet" / "data", target_is_directory=True)
    # Commands run from the repository's root and some read a committed file of a report (a map, a checkpoint).
    (tmp_path / "reports").symlink_to(ROOT / "reports", target_is_directory=True)
    for block in page_blocks:
        assert block.directive is not None, (
            f"{block.where}: a shell block with a command to run needs a `<!-- test: ... -->` comment above it "
            "(its sizes, or nothing to run it as written, or `skip: <reason>`; see tests/test_docs.py)"
        )
        if block.directive.skip:
            continue
        for command in commands(block.code):
            assert "$" not in command, f"{block.where}: {command!r} expands a shell variable; write the command out"
            variables, argv = assignments(sized(command, block.directive.args))
            argv = interpreter_argv(argv)
            run = subprocess.run(argv, cwd=tmp_path, env={**child_env(), **variables}, capture_output=True, text=True,
                                 timeout=TIMEOUT_S, check=False)  # fmt: skip
            assert run.returncode == 0, f"{block.where}: {shlex.join(argv[1:])} exited {run.returncode}:\n" + (
                run.stdout[-2000:] + run.stderr[-3000:]
            )


ENGINE_BLOCKS = [b for b in ALL if b.lang == "python" and b.directive and b.directive.engines]


@pytest.mark.slow
@pytest.mark.parametrize("block", ENGINE_BLOCKS, ids=[b.where for b in ENGINE_BLOCKS])
def test_engine_blocks_run(block: Block, tmp_path: Path) -> None:
    python = ENGINES_VENV / "bin" / "python"
    if not python.exists():
        pytest.skip(
            f"{block.where} runs in the engines venv, absent at {ENGINES_VENV} (bash scripts/engines.sh --setup)"
        )
    script = tmp_path / "snippet.py"
    script.write_text(block.code, encoding="utf-8")
    run = subprocess.run([str(python), str(script)], cwd=tmp_path, env=child_env(), capture_output=True, text=True,
                         timeout=TIMEOUT_S, check=False)  # fmt: skip
    assert run.returncode == 0, f"{block.where} exited {run.returncode}:\n" + run.stdout[-2000:] + run.stderr[-3000:]


# ---- the rules the test reads by ----


def test_the_directive_rules() -> None:
    assert sized("uamfleet train --total-timesteps 3000000 --seed 1", ["--total-timesteps", "512"]) == [
        "uamfleet", "train", "--total-timesteps", "512", "--seed", "1"
    ]  # fmt: skip
    assert sized("uamfleet bench --settings 4x48 8x96 --count 30", ["--settings", "2x12", "--jobs", "1"]) == [
        "uamfleet", "bench", "--settings", "2x12", "--count", "30", "--jobs", "1"
    ]  # fmt: skip
    assert sized("uamfleet train --thresholds -7 -6 --seed 1", ["--thresholds", "-3"])[2:5] == [
        "--thresholds", "-3", "--seed"
    ]  # fmt: skip
    assert commands("bash scripts/setup.sh   # set-up\nuamfleet a \\\n  --b 1   # note\n# uamfleet c\npython -m x") == [
        "uamfleet a --b 1",
        "python -m x",
    ]
    assert commands('OMP_NUM_THREADS=1 A= uamfleet a\nL="--b 1"\nOMP_NUM_THREADS=1 .venv/bin/python x.py') == [
        "OMP_NUM_THREADS=1 A= uamfleet a"
    ]
    assert assignments(sized("OMP_NUM_THREADS=1 uamfleet a --n 9", ["--n", "1"])) == (
        {"OMP_NUM_THREADS": "1"}, ["uamfleet", "a", "--n", "1"]
    )  # fmt: skip
    directive = parse_directive(" slow needs:sionna --cell-m 50 ", "here")
    assert (directive.slow, directive.needs, directive.args, directive.skip) == (True, ["sionna"], ["--cell-m", "50"],
                                                                                 None)  # fmt: skip
    assert parse_directive(" apart --count 1 ", "here").apart and not directive.apart
    assert parse_directive(" skip: needs a GPU ", "here").skip == "needs a GPU"
    with pytest.raises(AssertionError, match="needs a reason"):
        parse_directive(" skip: ", "here")


def test_every_block_is_tested_or_says_why_not() -> None:
    """A python or bash block is run by a test above; a skipped one names its reason (checked when parsed); every
    page's blocks are closed (checked when parsed)."""
    langs = {b.lang for b in ALL if b.page.name in ("README.md",) or "docs" in b.page.parts}
    assert "python" in langs and "bash" in langs
    run = [b for b in ALL if b.lang == "python" or (b.lang == "bash" and commands(b.code))]
    assert len(run) >= 10, [b.where for b in run]
    for block in run:
        if block.directive and block.directive.engines:
            assert block.lang == "python", f"{block.where}: `engines` is for python blocks"


def test_the_split_runs_every_quick_block_in_exactly_one_default_test() -> None:
    """``apart`` moves a block into a test of its own: the split loses no block and runs none twice."""
    assert any(is_apart(b) for b in ALL), "docs/results.md's long blocks are `apart`"
    for lang in ("python", "bash"):
        ran = [b.where for p in params(lang) if not p.marks for b in p.values[0]]
        quick = [b.where for b in ALL if b.lang == lang and not is_slow(b) and not (b.directive and b.directive.engines)
                 and (lang == "python" or commands(b.code))]  # fmt: skip
        assert sorted(ran) == sorted(quick)


# ---- the README ----

README = (ROOT / "README.md").read_text(encoding="utf-8")
# The README's test command, also .ci/run's and the landing and getting-started pages' (two workers: pytest-xdist).
TEST_COMMAND = ".venv/bin/python -m pytest -q -n 2"


def test_the_readme_is_short_and_has_what_a_newcomer_needs() -> None:
    lines = README.splitlines()
    assert len(lines) <= 150, f"README.md has {len(lines)} lines; keep it at most 150 (move the rest to docs/)"
    assert "bash scripts/setup.sh && .venv/bin/python -m eval.quickstart" in README  # the main job (.ci/run)
    assert f"bash scripts/setup.sh && {TEST_COMMAND}\n" in README  # the test command (.ci/run)
    assert re.search(r"^while env\.agents:$", README, re.M), "the README shows a `while env.agents:` loop"
    assert re.search(r"!\[[^\]]+\]\(docs/(figures|screenshots)/[^)]+\.png\)", README), "one picture"
    begin, end = "<!-- docs-tables:begin readme -->", "<!-- docs-tables:end readme -->"
    assert README.index(begin) < README.index(end), "the results table sits between the docs-tables markers"
    table = README[README.index(begin) : README.index(end)]
    assert table.count("\n|") >= 4, "a results table between the markers"
    for target in ("LICENSE", "CITATION.cff", "docs/getting-started.md", "docs/environments.md", "docs/rules.md",
                   "docs/results.md", "docs/benchmarks.md", "docs/training/scaling.md", "docs/cities.md"):  # fmt: skip
        assert f"]({target})" in README, f"the README links {target}"
    for link in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README):
        if not link.startswith("http"):
            assert (ROOT / link).exists(), f"the README links {link}, which does not exist"


def expected_output(text: str) -> str:
    begin, end = "<!-- quickstart-output:begin -->", "<!-- quickstart-output:end -->"
    return text[text.index(begin) : text.index(end)]


@pytest.mark.parametrize("page", ["docs/index.md", "docs/getting-started.md"])
def test_the_pages_show_the_readmes_expected_output(page: str) -> None:
    assert expected_output((ROOT / page).read_text(encoding="utf-8")) == expected_output(README)


@pytest.mark.parametrize("page", ["docs/index.md", "docs/getting-started.md"])
def test_the_pages_show_the_readmes_test_command(page: str) -> None:
    """(.ci/run's: tests/test_docs_site.py.)"""
    lines = (ROOT / page).read_text(encoding="utf-8").splitlines()
    assert f"bash scripts/setup.sh && {TEST_COMMAND}" in lines, f"{page} should show the README's test command"


def test_the_layout_page_is_the_layer_table() -> None:
    text = (ROOT / "docs" / "layout.md").read_text(encoding="utf-8")
    table = text[text.index("<!-- layers:begin -->") : text.index("<!-- layers:end -->")]
    documented = []
    for row in table.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].isdigit():
            documented.append((int(cells[0]), tuple(re.findall(r"`([\w.]+)`", cells[1]))))
    assert documented == [(rank, tuple(names)) for rank, names in LAYERS], (
        "docs/layout.md's layer table differs from tests/test_layers.py's LAYERS: update the page"
    )
