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
- ``command``: the command that wrote the CSV, printed above the table in a ``bash`` block;
- ``note``: a line printed under the table;
- ``parts``: a list of other tables' names, rendered one after another (then no other key is needed).

Each row also has the column ``csv``: the file name of the CSV it was read from (without its folder).

An expression is Python arithmetic, comparisons, ``and`` / ``or`` / ``not`` and ``in`` over the row's columns
(a value that parses as a number is a float) and constants; nothing else (no calls, no attributes). A division by
zero gives NaN. Aggregations skip NaN values; a cell without values prints "–".
"""

from __future__ import annotations

import ast
import csv
import math
import sys
import tomllib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from uamfleet.cli._common import UNDEFINED, run
from uamfleet.io import write_text_atomic

ROOT = Path(__file__).resolve().parents[2]
"""The repository root: the paths of ``tables.toml`` and of the pages are relative to it."""

TABLES = Path("docs/results/tables.toml")
"""The definition of every table, relative to the root."""

BEGIN, END = "<!-- docs-tables:begin {} -->", "<!-- docs-tables:end {} -->"
"""The lines that open and close a generated table in a Markdown file."""

REFRESH_HINT = "run `uamfleet docs-tables` to refresh the results pages (docs/results.md, README.md) from the CSVs"
"""The line a results command prints after writing its CSV: the pages are generated from the CSVs, not by it."""

Value = float | str


def _mean_ci(values: np.ndarray) -> tuple[float, float]:
    """The mean and the half-width of its 95 % interval (normal approximation, 1.96 standard errors; 0 for one
    value), as ``eval.benchmark`` and ``eval.fleet_benchmark`` print them."""
    half = 1.96 * values.std(ddof=1) / math.sqrt(len(values)) if len(values) > 1 else 0.0
    return float(values.mean()), float(half)


AGGREGATIONS: dict[str, Callable[[np.ndarray], float | tuple[float, float]]] = {
    "mean": lambda v: float(v.mean()),
    "mean_ci": _mean_ci,
    "median": lambda v: float(np.median(v)),
    "p95": lambda v: float(np.percentile(v, 95)),
    "min": lambda v: float(v.min()),
    "max": lambda v: float(v.max()),
    "sum": lambda v: float(v.sum()),
    "count": lambda v: float(len(v)),
}
"""The aggregations of a column's numeric values (besides ``first``, the group's first value as it is)."""


class TablesError(ValueError):
    """A table definition, a page's markers or a CSV that cannot make the table (one line, exit status 2)."""


# ---- expressions ----

_ALLOWED = (
    ast.Expression, ast.BoolOp, ast.And, ast.Or, ast.UnaryOp, ast.Not, ast.USub, ast.UAdd, ast.BinOp, ast.Add,
    ast.Sub, ast.Mult, ast.Div, ast.Compare, ast.Eq, ast.NotEq, ast.Lt, ast.LtE, ast.Gt, ast.GtE, ast.In, ast.NotIn,
    ast.Name, ast.Load, ast.Constant, ast.Tuple, ast.List,
)  # fmt: skip


@dataclass(frozen=True)
class Expression:
    """A checked expression over a row's columns (see the module docstring)."""

    text: str
    code: Any = field(compare=False, repr=False)
    names: frozenset[str] = field(compare=False, repr=False)

    @classmethod
    def parse(cls, text: Any, where: str) -> Expression:
        if not isinstance(text, str) or not text.strip():
            raise TablesError(f'{where}: {text!r} is not an expression; write one as a string, e.g. "td_m / 1000".')
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as err:
            raise TablesError(f"{where}: {text!r} is not a valid expression ({err.msg}); fix its syntax.") from None
        for node in ast.walk(tree):
            if not isinstance(node, _ALLOWED):
                raise TablesError(
                    f"{where}: {text!r} uses {type(node).__name__}; an expression may use only columns, constants, "
                    "arithmetic, comparisons, and/or/not and in."
                )
        names = frozenset(n.id for n in ast.walk(tree) if isinstance(n, ast.Name))
        return cls(text, compile(tree, where, "eval"), names)

    def __call__(self, row: dict[str, Value]) -> Any:
        try:
            return eval(self.code, {"__builtins__": {}}, row)  # the nodes are checked in parse
        except ZeroDivisionError:
            return math.nan
        except TypeError as err:
            raise TablesError(f"the expression {self.text!r} cannot be computed on a row ({err}); fix it.") from None


def parse_value(text: str) -> Value:
    """A CSV cell: a float when it parses as one (``nan`` included), else the text."""
    try:
        return float(text)
    except ValueError:
        return text


# ---- table definitions ----


@dataclass(frozen=True)
class Column:
    title: str
    value: Expression
    agg: str = "first"
    format: str = ""
    when: Expression | None = None
    scale: float = 1.0
    align: str = "right"
    over: Expression | None = None


@dataclass(frozen=True)
class Table:
    name: str
    csv: tuple[str, ...]
    columns: tuple[Column, ...]
    where: Expression | None = None
    group_by: tuple[str, ...] = ()
    order: tuple[Value, ...] | None = None
    sort: tuple[tuple[int, tuple[Value, ...]], ...] = ()
    pivot: str | None = None
    pivot_order: tuple[Value, ...] | None = None
    cell: Column | None = None
    command: str = ""
    note: str = ""
    refs: tuple[tuple[str, Expression, tuple[str, ...]], ...] = ()
    labels: tuple[tuple[str, str], ...] = ()
    parts: tuple[str, ...] = ()


_TABLE_KEYS = {"csv", "columns", "where", "group_by", "order", "ref", "refs", "pivot", "pivot_order", "cell", "command",
               "note", "labels", "parts"}  # fmt: skip
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
        note=str(spec.get("note", "")),
    )


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


# ---- computing a table ----


def read_rows(paths: Iterable[str], root: Path) -> list[dict[str, Value]]:
    rows: list[dict[str, Value]] = []
    for name in paths:
        path = root / name
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such CSV; fix the table's csv path (relative to {root}).")
        with path.open(encoding="utf-8", newline="") as f:
            rows += [{**{k: parse_value(v) for k, v in r.items()}, "csv": path.name} for r in csv.DictReader(f)]
    return rows


def _key(row: dict[str, Value], columns: Sequence[str], table: str) -> tuple[Value, ...]:
    try:
        return tuple(row[c] for c in columns)
    except KeyError as err:
        raise TablesError(f"tables.{table}: no column {err.args[0]!r} in its CSV; use one of {sorted(row)}.") from None


def _with_refs(table: Table, rows: list[dict[str, Value]]) -> list[dict[str, Value]]:
    """Each row with each reference row's columns as ``NAME_<column>`` (NaN where it has none)."""
    for name, where, on in table.refs:
        try:
            refs = {_key(r, on, table.name): r for r in rows if where(r)}
        except NameError as err:
            raise TablesError(f"tables.{table.name}.refs.{name}: {err}; name one of the CSV's columns.") from None
        blank = {f"{name}_{c}": math.nan for c in rows[0]} if rows else {}
        out = []
        for r in rows:
            ref = refs.get(_key(r, on, table.name))
            out.append({**r, **({f"{name}_{c}": v for c, v in ref.items()} if ref else blank)})
        rows = out
    return rows


def _cell(column: Column, rows: list[dict[str, Value]], table: str) -> str:
    """One column's text for the rows of one line."""
    try:
        if column.when is not None:
            rows = [r for r in rows if column.when(r)]
        values = [column.value(r) for r in rows]
    except NameError as err:
        raise TablesError(f"tables.{table}: {err}; an expression names the CSV's columns (or ref_<column>).") from None
    if column.agg == "first":
        return _format(values[0] if values else math.nan, column)
    numbers = _finite(values)
    if not len(numbers):
        return UNDEFINED
    result = AGGREGATIONS[column.agg](numbers)
    if isinstance(result, tuple):  # a mean and its half-interval, which carries no sign
        mean, half = result
        return f"{_format(mean, column)} ± {_format(half, replace(column, format=column.format.lstrip('+')))}"
    if column.over is not None:  # agg is a single figure here (parse refuses over with mean_ci)
        below = _finite([column.over(r) for r in rows])
        result = result / float(AGGREGATIONS[column.agg](below)) if len(below) else math.nan  # type: ignore[arg-type]
    return _format(result, column)


def _finite(values: Sequence[Any]) -> np.ndarray:
    numbers = np.array([float(v) for v in values], dtype=float)
    return numbers[~np.isnan(numbers)]


def _format(value: Any, column: Column) -> str:
    if isinstance(value, str):
        return value
    value = float(value) * column.scale
    if not math.isfinite(value):
        return UNDEFINED
    spec = column.format or "g"
    try:
        return f"{round(value) if spec.endswith('d') else value:{spec}}"  # "d": counts, rounded to whole numbers
    except ValueError:
        raise TablesError(
            f"format {spec!r} of the column {column.title!r} is no number format; use e.g. ',.1f'."
        ) from None


def _groups(table: Table, rows: list[dict[str, Value]], columns: tuple[str, ...]) -> dict[tuple[Value, ...], list]:
    groups: dict[tuple[Value, ...], list[dict[str, Value]]] = {}
    for r in rows:
        groups.setdefault(_key(r, columns, table.name), []).append(r)
    return groups


def _ordered(keys: Iterable[Any], order: tuple[Value, ...] | None, pick: Callable[[Any], Value]) -> list[Any]:
    keys = list(keys)
    if order is None:
        return keys
    return [k for o in order for k in keys if pick(k) == o]


def render(table: Table, root: Path = ROOT, tables: dict[str, Table] | None = None) -> str:
    """The Markdown of ``table`` computed from its CSV files under ``root``: its command, the table, its note (or
    its ``parts``, tables of ``tables``, one after another)."""
    if table.parts:
        if tables is None:
            raise TablesError(f"tables.{table.name} is made of parts; render it with the tables that define them.")
        return "\n\n".join(render(tables[part], root) for part in table.parts)
    rows = _selected_rows(table, root)
    groups: dict[tuple[Value, ...], list] = (
        _groups(table, rows, table.group_by) if table.group_by else {(i,): [r] for i, r in enumerate(rows)}
    )
    pivots = _pivots(table, rows)
    out = ["```bash", table.command, "```", ""] if table.command else []
    out += _header(table, pivots)
    out += ["| " + " | ".join(_line(table, groups[key], pivots)) + " |" for key in _line_keys(table, groups)]
    if table.note:
        out += ["", table.note]
    return "\n".join(out)


def _selected_rows(table: Table, root: Path) -> list[dict[str, Value]]:
    """The rows of the table's CSV files, with their reference rows, that pass its ``where`` (at least one)."""
    rows = _with_refs(table, read_rows(table.csv, root))
    if table.where is not None:
        try:
            rows = [r for r in rows if table.where(r)]
        except NameError as err:
            raise TablesError(f"tables.{table.name}.where: {err}; name one of the CSV's columns.") from None
    if not rows:
        raise TablesError(f"tables.{table.name}: no row of {', '.join(table.csv)} passes its where; fix the filter.")
    return rows


def _line_keys(table: Table, groups: dict[tuple[Value, ...], list]) -> list[tuple[Value, ...]]:
    """The groups' keys in the table's ``order`` (or as they first appear), kept and sorted by its ``sort``."""
    keys = _ordered(groups, table.order, lambda k: k[0])
    for index, values in table.sort:
        keys = [k for k in keys if k[index] in values]
    keys.sort(key=lambda k: tuple(values.index(k[i]) for i, values in table.sort))
    return keys


def _pivots(table: Table, rows: list[dict[str, Value]]) -> list[Value]:
    """The values of the pivot column that become columns (none without a pivot)."""
    if table.pivot is None or table.cell is None:
        return []
    seen = dict.fromkeys(_key(r, (table.pivot,), table.name)[0] for r in rows)
    return _ordered(seen, table.pivot_order, lambda v: v)


def _header(table: Table, pivots: list[Value]) -> list[str]:
    """The title line and the alignment line, the pivot's columns after the table's own."""
    titles = [c.title for c in table.columns]
    aligns = [c.align for c in table.columns]
    if table.cell is not None:
        titles += [_format(v, table.cell) if not isinstance(v, str) else v for v in pivots]
        aligns += [table.cell.align] * len(pivots)
    return ["| " + " | ".join(titles) + " |", "|" + "|".join("---:" if a == "right" else "---" for a in aligns) + "|"]


def _line(table: Table, rows: list[dict[str, Value]], pivots: list[Value]) -> list[str]:
    """The cells of one line: each column's (a ``first`` one through the labels), then each pivot value's."""
    labels = dict(table.labels)
    cells = [_cell(c, rows, table.name) for c in table.columns]
    cells = [labels.get(x, x) if c.agg == "first" else x for c, x in zip(table.columns, cells, strict=True)]
    if table.pivot is not None and table.cell is not None:
        cells += [_cell(table.cell, [r for r in rows if r[table.pivot] == v], table.name) for v in pivots]
    return cells


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
