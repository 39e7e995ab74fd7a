"""The results tables of the documentation, generated from the committed CSVs of ``docs/results/``.

    uamfleet docs-tables                        # fills every table of docs/results.md and docs/benchmarks.md
    uamfleet docs-tables --check                # exit status 1 (and the pages named) if a page differs
    uamfleet docs-tables --out-dir /tmp/pages   # writes the filled pages there, the committed ones untouched
    uamfleet docs-tables --pages README.md      # fills the tables marked in another Markdown file

``docs/results/tables.toml`` defines each table: its CSV file(s), a row filter, the group-by, and its columns
(an expression over a row's columns, an aggregation and a format). A page holds a table between the lines
``<!-- docs-tables:begin NAME -->`` and ``<!-- docs-tables:end NAME -->``; everything outside the markers is the
page's own text and is kept byte for byte. Each filled page is written atomically.

The table entries of ``tables.toml``:

- ``csv``: a path or a list of paths (relative to the repository root), their rows read in order;
- ``where``: an expression a row must satisfy (``"feasibility == 'endpoint_block' and method in ('replan',)"``);
- ``group_by``: the columns whose values make one line of the table (without it, one line per row). Lines come in
  the order they first appear, or in the order of ``order``: a list of the first group column's values (which also
  drops the others), or ``{column = [values], ...}``, sorted by each named group column in that order of its
  values (dropping the others);
- ``refs``: ``{NAME = {where = ..., on = [...]}}``, a reference row per row and name: the row satisfying ``where``
  with the same values of the ``on`` columns; an expression reads its columns as ``NAME_<column>`` (NaN where there
  is none); ``ref = {where, on}`` is the same with the name ``ref``;
- ``columns``: a list of ``{title, value, agg, format, when, over, scale, align}``: ``value`` is an expression,
  ``when`` keeps only the rows where it holds, ``agg`` one of :data:`AGGREGATIONS` (``first`` by default),
  ``over`` a second expression whose aggregate divides the first (a ratio of means), ``format`` a Python format
  spec of the figure (``",.1f"``), ``scale`` a factor applied before formatting;
- ``labels``: ``{value = "text"}``, the text printed for a value in a column of agg ``first``;
- ``pivot``: a column whose values become columns (in the order they first appear, or ``pivot_order``), each
  cell the aggregation ``cell = {value, agg, format, when}`` of the group's rows with that value;
- ``command``: the command that wrote the CSV, printed above the table in a ``bash`` block, with ``test``;
- ``test``: how ``tests/test_docs.py`` runs the command, written as ``<!-- test: ... -->`` above its block: the
  sizes that replace the command's (``"--count 1 --jobs 1 --out-csv out.csv"``), ``slow``, ``apart``,
  ``needs:MODULE`` or ``skip: <reason>``; a ``command`` without ``test`` is refused, so that every documented
  command runs in a test;
- ``note``: a line printed under the table;
- ``parts``: a list of other tables' names, rendered one after another (then no other key is needed).

Each row also has the column ``csv``: the file name of the CSV it was read from (without its folder).

An expression is Python arithmetic, comparisons, ``and`` / ``or`` / ``not`` and ``in`` over the row's columns
(a value that parses as a number is a float) and constants; nothing else (no calls, no attributes). A division by
zero gives NaN. Aggregations skip NaN values; a cell without values prints "–".
"""

from __future__ import annotations

import sys
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uamfleet.cli._common import run
from uamfleet.cli.tables_render import (
    AGGREGATIONS,
    ROOT,
    Column,
    Expression,
    Table,
    TablesError,
    Value,
    render,
)
from uamfleet.io import write_text_atomic

__all__ = ["REFRESH_HINT", "TABLES", "Table", "TablesError", "cli", "fill", "generate", "load_tables", "render",
           "table_of", "write_table"]  # fmt: skip

TABLES = Path("docs/results/tables.toml")
"""The definition of every table, relative to the root."""

BEGIN, END = "<!-- docs-tables:begin {} -->", "<!-- docs-tables:end {} -->"
"""The lines that open and close a generated table in a Markdown file."""

REFRESH_HINT = "run `uamfleet docs-tables` to refresh the results pages (docs/results.md, README.md) from the CSVs"
"""The line a results command prints after writing its CSV: the pages are generated from the CSVs, not by it."""

# ---- table definitions ----

_TABLE_KEYS = {"csv", "columns", "where", "group_by", "order", "ref", "refs", "pivot", "pivot_order", "cell", "command",
               "test", "note", "labels", "parts"}  # fmt: skip
_COLUMN_KEYS = {"title", "value", "agg", "format", "when", "over", "scale", "align"}


def _column(spec: Any, where: str, title: str | None = None) -> Column:
    if not isinstance(spec, dict):
        raise TablesError(f"{where}: {spec!r} is not a table of column keys; write {{title = ..., value = ...}}.")
    if unknown := set(spec) - _COLUMN_KEYS:
        raise TablesError(f"{where}: unknown key(s) {sorted(unknown)}; the keys are {sorted(_COLUMN_KEYS)}.")
    agg = spec.get("agg", "first")
    if agg != "first" and agg not in AGGREGATIONS:
        raise TablesError(f"{where}: agg {agg!r} is not one of first, {', '.join(AGGREGATIONS)}; pick one of them.")
    value = Expression.parse(spec.get("value"), f"{where}.value")
    when = Expression.parse(spec["when"], f"{where}.when") if "when" in spec else None
    over = Expression.parse(spec["over"], f"{where}.over") if "over" in spec else None
    if over is not None and agg in ("first", "mean_ci"):
        raise TablesError(f"{where}: over needs a single-figure agg such as mean, not {agg!r}; change agg.")
    default_align = "left" if agg == "first" and "format" not in spec else "right"
    align = spec.get("align", default_align)
    if align not in ("left", "right"):
        raise TablesError(f"{where}: align {align!r} is neither 'left' nor 'right'; pick one.")
    scale = spec.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)):
        raise TablesError(f"{where}: scale {scale!r} is not a number; give one, e.g. 100.")
    return Column(str(spec.get("title", title or spec.get("value"))), value, agg, str(spec.get("format", "")), when,
                  float(scale), align, over)  # fmt: skip


def table_of(name: str, spec: Any) -> Table:
    """The checked :class:`Table` of one ``[tables.NAME]`` entry."""
    where = f"tables.{name}"
    if not isinstance(spec, dict):
        raise TablesError(f"{where} is not a table; write it as [tables.{name}] with csv = ... and columns = [...].")
    if unknown := set(spec) - _TABLE_KEYS:
        raise TablesError(f"{where}: unknown key(s) {sorted(unknown)}; the keys are {sorted(_TABLE_KEYS)}.")
    if "parts" in spec:
        return Table(name=name, csv=(), columns=(), parts=_parts(spec, where))
    paths = _csv_paths(spec, where)
    columns = spec.get("columns", [])
    if not isinstance(columns, list) or not columns:
        raise TablesError(f"{where}.columns: give a list of at least one column {{title = ..., value = ...}}.")
    refs = _ref_specs(spec, where)
    labels = _labels(spec, where)
    pivot = _pivot(spec, where)
    group_by = tuple(spec.get("group_by", ()))
    return Table(
        name=name,
        csv=paths,
        columns=tuple(_column(c, f"{where}.columns[{i}]") for i, c in enumerate(columns)),
        where=Expression.parse(spec["where"], f"{where}.where") if "where" in spec else None,
        group_by=group_by,
        order=tuple(spec["order"]) if isinstance(spec.get("order"), list) else None,
        sort=_sort(spec.get("order"), group_by, where),
        refs=tuple(
            (n, Expression.parse(r["where"], f"{where}.refs.{n}.where"), tuple(r["on"])) for n, r in refs.items()
        ),
        labels=labels,
        pivot=pivot,
        pivot_order=tuple(spec["pivot_order"]) if "pivot_order" in spec else None,
        cell=_column(spec["cell"], f"{where}.cell", title="") if pivot is not None else None,
        command=str(spec.get("command", "")),
        test=_test(spec, where),
        note=str(spec.get("note", "")),
    )


def _test(spec: dict[str, Any], where: str) -> str:
    """The entry's ``test`` directive, which a ``command`` needs (and only a command takes)."""
    test = spec.get("test")
    if ("command" in spec) != (test is not None) or not isinstance(test, (str, type(None))):
        raise TablesError(
            f'{where}: a command needs test = "<sizes, slow, needs:MODULE or skip: reason>" and test a '
            "command (tests/test_docs.py runs the command sized by it); give both or neither."
        )
    return test or ""


def _parts(spec: dict[str, Any], where: str) -> tuple[str, ...]:
    """The table names of a ``parts = [...]`` entry (its only key)."""
    parts = spec["parts"]
    if not isinstance(parts, list) or not parts or not all(isinstance(p, str) for p in parts) or len(spec) > 1:
        raise TablesError(f"{where}: parts = {parts!r} must be a list of table names and the entry's only key.")
    return tuple(parts)


def _csv_paths(spec: dict[str, Any], where: str) -> tuple[str, ...]:
    """The entry's ``csv``: one path or a list of paths."""
    paths = spec.get("csv")
    paths = [paths] if isinstance(paths, str) else paths
    if not paths or not all(isinstance(p, str) for p in paths):
        raise TablesError(f"{where}.csv: {spec.get('csv')!r} names no CSV file; give a path or a list of paths.")
    return tuple(paths)


def _ref_specs(spec: dict[str, Any], where: str) -> dict[str, dict[str, Any]]:
    """The entry's ``refs`` with its ``ref`` under the name ``ref``, each holding a ``where`` and an ``on``."""
    refs = dict(spec.get("refs", {}))
    if "ref" in spec:
        refs["ref"] = spec["ref"]
    for ref_name, ref in refs.items():
        if not isinstance(ref, dict) or "where" not in ref or not ref.get("on"):
            raise TablesError(
                f'{where}.refs.{ref_name}: write {{where = "method == \'best_known\'", on = ["instance"]}}.'
            )
    return refs


def _labels(spec: dict[str, Any], where: str) -> tuple[tuple[str, str], ...]:
    """The entry's ``labels`` as (value, text) pairs."""
    labels = spec.get("labels", {})
    if not isinstance(labels, dict):
        raise TablesError(f'{where}.labels: write labels = {{value = "text"}}.')
    return tuple((str(k), str(v)) for k, v in labels.items())


def _pivot(spec: dict[str, Any], where: str) -> str | None:
    """The entry's ``pivot`` column, which comes with a ``cell`` (or neither is given)."""
    pivot = spec.get("pivot")
    if (pivot is None) != ("cell" not in spec):
        raise TablesError(f"{where}: pivot and cell go together; give both (or neither).")
    return pivot


def _sort(order: Any, group_by: tuple[str, ...], where: str) -> tuple[tuple[int, tuple[Value, ...]], ...]:
    """``order = {column = [values]}`` as (index of the group column, its values in order) pairs."""
    if not isinstance(order, dict):
        return ()
    if unknown := set(order) - set(group_by):
        raise TablesError(f"{where}.order: {sorted(unknown)} not in group_by {list(group_by)}; order group columns.")
    return tuple((group_by.index(c), tuple(v)) for c, v in order.items())


def load_tables(path: Path) -> tuple[dict[str, Table], list[str]]:
    """The tables of a ``tables.toml`` and its ``pages`` (the Markdown files filled by default)."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise TablesError(f"{path}: not valid TOML ({err}); fix the file.") from None
    tables = data.get("tables", {})
    if not isinstance(tables, dict) or not tables:
        raise TablesError(f"{path} defines no [tables.NAME] entry; add one.")
    pages = data.get("pages", [])
    if not isinstance(pages, list) or not all(isinstance(p, str) for p in pages):
        raise TablesError(f'{path}: pages = {pages!r} is not a list of paths; write pages = ["docs/results.md"].')
    out = {name: table_of(name, spec) for name, spec in tables.items()}
    for table in out.values():
        for part in table.parts:
            if part not in out or out[part].parts:
                raise TablesError(f"tables.{table.name}.parts: {part!r} is not a table without parts; fix the name.")
    return out, pages


# ---- pages ----


def fill(text: str, tables: dict[str, Table], root: Path = ROOT, where: str = "the page") -> str:
    """``text`` with every marked table recomputed (the text between its begin and end lines replaced)."""
    out: list[str] = []
    lines = text.split("\n")
    i = 0
    while i < len(lines):
        line = lines[i]
        out.append(line)
        name = _marker(line, BEGIN)
        i += 1
        if name is None:
            if (stray := _marker(line, END)) is not None:
                raise TablesError(f"{where}, line {i}: an end marker of {stray!r} without its begin line; remove it.")
            continue
        if name not in tables:
            raise TablesError(f"{where}, line {i}: no table {name!r} in {TABLES}; define it or fix the marker.")
        end = END.format(name)
        try:
            j = lines.index(end, i)
        except ValueError:
            raise TablesError(f"{where}, line {i}: the table {name!r} has no line {end!r}; add it.") from None
        out += [render(tables[name], root, tables), end]
        i = j + 1
    return "\n".join(out)


def _marker(line: str, pattern: str) -> str | None:
    head, tail = pattern.split("{}")
    stripped = line.strip()
    if stripped.startswith(head) and stripped.endswith(tail) and line == stripped:
        name = stripped[len(head) : len(stripped) - len(tail)]
        return name if name and " " not in name else None
    return None


def write_table(path: str | Path, name: str, tables: dict[str, Table], root: Path = ROOT) -> Path:
    """Fill the table ``name`` between its markers in the Markdown file ``path``, atomically (the file must hold
    the two marker lines; the other marked tables of the file are filled too)."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    if BEGIN.format(name) not in text.split("\n"):
        raise TablesError(
            f"{path} has no line {BEGIN.format(name)!r}; put it and {END.format(name)!r} where the table goes."
        )
    return write_text_atomic(path, fill(text, tables, root, str(path)))


def generate(
    root: Path = ROOT, pages: Sequence[str] | None = None, out_dir: Path | None = None, tables_path: Path | None = None
) -> list[Path]:
    """Fill the pages (by default those of ``tables.toml``) from the CSVs under ``root``; write each to ``out_dir``
    (at its path relative to the root) or in place. The paths of the pages whose text changed."""
    tables, default_pages = load_tables(tables_path or root / TABLES)
    changed = []
    for page in pages if pages is not None else default_pages:
        source = root / page
        if not source.is_file():
            raise FileNotFoundError(f"{source}: no such page; fix the path (relative to {root}).")
        text = source.read_text(encoding="utf-8")
        new = fill(text, tables, root, str(page))
        target = source if out_dir is None else out_dir / page
        if out_dir is not None or new != text:
            write_text_atomic(target, new)
        if new != text:
            changed.append(target)
    return changed


@dataclass
class Args:
    root: Path = ROOT
    """the repository root: tables.toml, the CSVs and the pages are read below it"""
    pages: tuple[str, ...] | None = None
    """the Markdown files to fill, relative to the root (default: the pages listed in docs/results/tables.toml)"""
    out_dir: Path | None = None
    """write the filled pages below this folder instead of over the committed ones"""
    check: bool = False
    """write nothing; exit status 1, naming each page, when a page differs from its regenerated text"""


def main(args: Args) -> int:
    root = args.root.resolve()
    if args.check:
        tables, default_pages = load_tables(root / TABLES)
        stale = []
        for page in args.pages if args.pages is not None else default_pages:
            text = (root / page).read_text(encoding="utf-8")
            if fill(text, tables, root, page) != text:
                stale.append(page)
        for page in stale:
            print(f"{page} differs from its CSVs; run `uamfleet docs-tables` and commit it.", file=sys.stderr)
        return 1 if stale else 0
    changed = generate(root, args.pages, args.out_dir)
    print(f"{len(changed)} page(s) changed" + "".join(f"\n  {p}" for p in changed))
    return 0


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet docs-tables") -> int:
    """The ``uamfleet docs-tables`` command (``python -m uamfleet.cli.docs_tables``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.docs_tables"))
