"""The rows and formats of the results tables: a table definition (:class:`Table`, :class:`Column`, checked
:class:`Expression` s) computed from its CSV files into Markdown by :func:`render`. The definitions are read from
``docs/results/tables.toml`` and the pages written by :mod:`uamfleet.cli.docs_tables`, whose docstring documents
the keys, the expressions and the aggregations."""

from __future__ import annotations

import ast
import csv
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from uamfleet.cli._common import UNDEFINED

ROOT = Path(__file__).resolve().parents[2]
"""The repository root: the paths of ``tables.toml`` and of the pages are relative to it."""

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
    test: str = ""
    note: str = ""
    refs: tuple[tuple[str, Expression, tuple[str, ...]], ...] = ()
    labels: tuple[tuple[str, str], ...] = ()
    parts: tuple[str, ...] = ()


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
    directive = f"<!-- test: {table.test} -->" if table.test else "<!-- test: -->"  # how tests/test_docs.py runs it
    out = [directive, "```bash", table.command, "```", ""] if table.command else []
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
