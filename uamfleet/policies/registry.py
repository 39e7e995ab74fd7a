"""The one registry of policies: every planner, dispatcher, learned policy and search wrapper by name, with typed
options (a frozen dataclass per policy).

    from uamfleet import policies
    policies.available()                      # {name: (kind, OptionsClass)}
    planner = policies.make("replan", beam=32)
    search = policies.make("guided", base=("learned", {"source": "berlin"}), top_k=8)

A search wrapper (kind ``search``) takes its base as ``base=``: a policy object, a ``(name, options)`` pair or a
name (:func:`uamfleet.policies.names.parse` reads the text form ``guided:top_k=8(learned:source=berlin)``).
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, Literal, Union

from uamfleet.checks import ConfigError

Kind = Literal["planner", "dispatcher", "learned", "search"]
KINDS: tuple[str, ...] = ("planner", "dispatcher", "learned", "search")
"""The kinds of policy :func:`available` names."""
BASE = "base"
"""The option of a search wrapper that holds the policy it searches over."""
DEFAULT_BASE: tuple[str, dict[str, Any]] = ("learned", {})
"""The base of a search wrapper given none: the shipped generalist (``learned``'s defaults)."""


class PolicyNameError(ConfigError):
    """An unknown policy name or option, or an option value of the wrong type or range (a ``ValueError``)."""


class NoSuchPolicy(PolicyNameError):
    """A name of no policy: unknown to the registry, or a published figure's label."""


@dataclasses.dataclass(frozen=True)
class NoOptions:
    """A policy without options."""


@dataclasses.dataclass(frozen=True)
class Entry:
    """A registered policy: its kind, options class and builder ``build(options, base)`` (``base`` is the built
    base policy of a search wrapper, None for the other kinds)."""

    kind: str
    options: type
    build: Callable[[Any, Any], Any]
    default_base: Any = DEFAULT_BASE  # a search wrapper's base when make() is given none


_REGISTRY: dict[str, Entry] = {}


def register(
    name: str, kind: str, options: type, build: Callable[[Any, Any], Any], default_base: Any = DEFAULT_BASE
) -> None:
    """Register the policy ``name`` of ``kind`` (:data:`KINDS`), its frozen options dataclass and its builder
    ``build(options, base)`` (a search wrapper: with ``default_base`` when given none); a name registered twice is
    refused."""
    if kind not in KINDS:
        raise PolicyNameError(f"policy {name!r}: kind {kind!r} is none of {KINDS}; register it as one of those.")
    if not (dataclasses.is_dataclass(options) and options.__dataclass_params__.frozen):  # type: ignore[attr-defined]
        raise PolicyNameError(f"policy {name!r}: options {options!r} must be a frozen dataclass; declare it so.")
    if name in _REGISTRY:
        raise PolicyNameError(f"policy {name!r} is registered already (as {_REGISTRY[name].kind}); pick another name.")
    _REGISTRY[name] = Entry(kind, options, build, default_base)


def available(kind: str | None = None) -> dict[str, tuple[str, type]]:
    """``{name: (kind, OptionsClass)}`` of every registered policy (of ``kind`` only, when given)."""
    if kind is not None and kind not in KINDS:
        raise PolicyNameError(f"kind {kind!r} is none of {KINDS}; ask for one of those or for all (None).")
    return {name: (e.kind, e.options) for name, e in _REGISTRY.items() if kind is None or e.kind == kind}


def entry(name: str) -> Entry:
    """The registration of ``name``; PolicyNameError listing the registered names when there is none."""
    if not isinstance(name, str) or name not in _REGISTRY:
        raise NoSuchPolicy(f"unknown policy {name!r}; the registered policies are {', '.join(_REGISTRY)}.")
    return _REGISTRY[name]


def _type_name(hint: Any) -> str:
    """``int``, ``float | None``, ``'world'`` …: a hint as a user reads it."""
    origin = typing.get_origin(hint)
    if origin in (Union, types.UnionType):
        return " | ".join(_type_name(h) for h in typing.get_args(hint))
    if origin is Literal:
        return " | ".join(repr(v) for v in typing.get_args(hint))
    if origin is tuple:
        return f"{_type_name(typing.get_args(hint)[0])}[;...]"
    return "none" if hint is type(None) else getattr(hint, "__name__", str(hint))


def _coerce_text(hint: Any, text: str) -> Any:
    """``text`` read as a value of ``hint`` (ValueError when it is none)."""
    if hint is type(None):
        if text == "none":
            return None
    elif hint is bool:
        if text in ("true", "false"):
            return text == "true"
    elif hint is int:
        return int(text)
    elif hint is float:
        value = float(text)
        if math.isfinite(value):
            return value
    elif hint is str:
        if text:
            return text
    raise ValueError(text)


def _coerce_union(hint: Any, value: Any) -> Any:
    members = sorted(typing.get_args(hint), key=lambda h: h is not type(None))  # none before a word
    for member in members:
        try:
            return coerce(member, value)
        except ValueError:
            continue
    raise ValueError(value)


def _coerce_scalar(hint: Any, value: Any) -> Any:
    """A Python ``value`` of the scalar type ``hint`` (an int is taken for a float)."""
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if hint is type(None) and value is None:
        return None
    if hint is not type(None) and type(value) is hint and (hint is not float or math.isfinite(value)):
        return value
    raise ValueError(value)


def coerce(hint: Any, value: Any) -> Any:
    """``value`` (a Python value, or the text of the string form) as a value of the type ``hint``: ``int``,
    ``float`` (an int is taken), ``bool``, ``str``, ``None``, a ``Literal``, a ``tuple[X, ...]`` (text: ``a;b``)
    or a union of these; ValueError when it is none of them."""
    origin = typing.get_origin(hint)
    if origin in (Union, types.UnionType):
        return _coerce_union(hint, value)
    if origin is Literal:
        if value in typing.get_args(hint):
            return value
        raise ValueError(value)
    if origin is tuple:
        items = value.split(";") if isinstance(value, str) else value
        if not isinstance(items, (tuple, list)) or not items:
            raise ValueError(value)
        return tuple(coerce(typing.get_args(hint)[0], item) for item in items)
    if isinstance(value, str) and hint is not str:
        return _coerce_text(hint, value)
    return _coerce_scalar(hint, value)


def _hints(options: type) -> dict[str, Any]:
    return typing.get_type_hints(options)


def options_of(name: str, given: Mapping[str, Any]) -> Any:
    """The options object of policy ``name`` from ``given`` (Python values or the string form's text; ``base``
    excluded); PolicyNameError naming an unknown option (and listing the policy's) or a value of the wrong type or
    range."""
    cls = entry(name).options
    hints = _hints(cls)
    values = {}
    for key, value in given.items():
        if key not in hints:
            known = ", ".join(hints) or "none"
            raise PolicyNameError(f"policy {name!r} has no option {key!r}; its options are: {known}.")
        try:
            values[key] = coerce(hints[key], value)
        except ValueError:
            raise PolicyNameError(
                f"policy {name!r}: {key}={value!r} is no {_type_name(hints[key])}; give one (e.g. "
                f"{key}={format_value(_default(cls, key))})."
            ) from None
    try:
        return cls(**values)
    except ValueError as err:  # the options' own range checks
        raise PolicyNameError(f"policy {name!r}: {err}") from None


def _default(cls: type, key: str) -> Any:
    field = next(f for f in dataclasses.fields(cls) if f.name == key)
    return field.default


def format_value(value: Any) -> str:
    """A value as the string form writes it: ``true``/``false``, ``none``, a number, a word, ``a;b`` for a tuple."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        return ";".join(format_value(v) for v in value)
    return str(value) if not isinstance(value, float) else repr(value)


def markdown_table() -> str:
    """The registry as a Markdown table: each policy's name, kind and options with their defaults (the table of
    ``docs/policies.md``)."""
    lines = ["| name | kind | options (defaults) |", "|---|---|---|"]
    for name, e in _REGISTRY.items():
        given = [f"`{f.name}={format_value(f.default)}`" for f in dataclasses.fields(e.options)]
        if e.kind == "search":
            given.append("`(BASE)`")
        lines.append(f"| `{name}` | {e.kind} | {', '.join(given) or 'none'} |")
    return "\n".join(lines)


def make(name: str, **options: Any) -> Any:
    """The policy ``name`` (:func:`available`) with ``options`` (its options dataclass's fields; a search wrapper
    also takes ``base``: a policy, a ``(name, options)`` pair or a name, default its registration's, mostly
    :data:`DEFAULT_BASE`)."""
    e = entry(name)
    base = options.pop(BASE, e.default_base if e.kind == "search" else None)
    if base is not None and e.kind != "search":
        raise PolicyNameError(f"policy {name!r} is a {e.kind}, which searches over no base; drop base= or wrap it.")
    built = options_of(name, options)
    if isinstance(base, str):
        base = make(base)
    elif isinstance(base, tuple):
        if len(base) != 2 or not isinstance(base[1], Mapping):
            raise PolicyNameError(f"policy {name!r}: base={base!r} is no (name, options) pair; give one or a policy.")
        base = make(base[0], **dict(base[1]))
    return e.build(built, base)


__all__ = [
    "BASE",
    "DEFAULT_BASE",
    "KINDS",
    "Entry",
    "Kind",
    "NoOptions",
    "NoSuchPolicy",
    "PolicyNameError",
    "available",
    "coerce",
    "entry",
    "format_value",
    "make",
    "markdown_table",
    "options_of",
    "register",
]
