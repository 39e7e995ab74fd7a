"""The one grammar of policy names, and the aliases that read every name recorded in the committed results.

    NAME[:OPTION=VALUE[,OPTION=VALUE...]]     batch_assignment:wait=1.0,release=true
    SEARCH(BASE)                              guided(learned:source=berlin)
    SEARCH:OPTIONS(BASE)                      hedge:futures=8,commit=4(learned:source=berlin)

A value is an int, a float, ``true``/``false``, ``none``, a bare word or path (no ``,``, ``(``, ``)``, ``=``), or
a tuple of those joined by ``;`` (``beams=256;128``). :func:`parse` gives ``(name, options)`` with typed values
(a search's ``base`` as a nested ``(name, options)`` pair); :func:`format` writes it back, and
``parse(format(name, options)) == (name, options)``. ``greedy(BASE)`` reads as ``argmax(BASE)``; bare ``greedy``
is the fleet dispatcher.

The names the benchmarks recorded before this grammar (the ``method`` and ``dispatcher`` columns of the CSVs under
``docs/results/``) are aliases, read by :func:`parse` into their call and kept unchanged as row keys:
``learned_guided_h40``, ``batch_assignment_value:100+wait=1+release+price=1000+guard=600``,
``batch_assignment_value:100+wait=1+release@refit_both`` (a value file of ``docs/results/assignment_value_refit/``),
``learned:berlin_fleet+window24`` (a shipped file ``uamfleet/data/pretrained/<stem>.pt`` or a run
``runs/<stem>/best.pt``). The single-taxi ``learned*`` names carry no checkpoint: the benchmark's ``--checkpoint``
is their base's ``source``.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path
from typing import Any

from uamfleet.baselines.assignment_value import VALUE_DISPATCHER
from uamfleet.baselines.fleet_dispatch import OPTION_SEPARATOR, DispatchOptions, split_options
from uamfleet.policies.registry import BASE, NoSuchPolicy, PolicyNameError, entry, format_value, options_of

Call = tuple[str, dict[str, Any]]
"""A policy's name and options, as :func:`uamfleet.policies.make` takes them."""

SEARCH_ALIAS = {"greedy": "argmax"}
"""Search names read in front of a base in parentheses: ``greedy(BASE)`` is ``argmax(BASE)``."""
LABELS: tuple[str, ...] = ("CPTSP", "PDPCC", "MSHA-RL", "straight (RL order)")
"""Row labels of published figures (the paper's numbers, ``cli/paper_numbers.py``): recorded names of no policy."""
_LEARNED: Call = ("learned", {})
_GUIDED: Call = ("guided", {BASE: _LEARNED})
RECORDED_METHODS: dict[str, Call] = {
    "learned": _LEARNED,
    "learned_guided": _GUIDED,
    "learned_guided_h40": ("guided", {"horizon": 40, BASE: _LEARNED}),
    "learned_guided_h80": ("guided", {"horizon": 80, BASE: _LEARNED}),
    "learned_guided_h120": ("guided", {"horizon": 120, BASE: _LEARNED}),
    "learned_hedge": ("hedge", {BASE: ("learned", {"traced": True})}),
    "learned_finish": ("finish", {BASE: _LEARNED}),
    "learned_guided_finish": ("finish", {BASE: _GUIDED}),
}
"""The single-taxi benchmark's recorded ``learned*`` methods and their calls (the base's ``source`` is the
benchmark's ``--checkpoint``)."""
_PLAIN = re.compile(r"[^,()=:;\s]+")
_RECORDED_LEARNED = re.compile(r"learned:([^+@:,()=\s]+)(?:\+window([0-9]+))?")
_MSHA = re.compile(r"msha-([A-Za-z0-9_]+)")


def _fail(text: object, why: str) -> PolicyNameError:
    return PolicyNameError(f"policy name {text!r}: {why}")


def _split_base(text: str) -> tuple[str, str | None]:
    """(``NAME[:OPTIONS]``, the base's text or None) of ``SEARCH[:OPTIONS](BASE)``."""
    if "(" not in text:
        if ")" in text:
            raise _fail(text, "a ')' without its '('; write SEARCH(BASE), e.g. guided(learned).")
        return text, None
    head, _, rest = text.partition("(")
    if not rest.endswith(")") or not rest[:-1]:
        raise _fail(text, "a base goes in parentheses at the end, e.g. guided:top_k=8(learned:source=berlin).")
    return head, rest[:-1]


def _read_options(text: str, head: str) -> tuple[str, dict[str, str]]:
    """(name, {option: value text}) of ``NAME[:OPTION=VALUE,...]``."""
    name, colon, tail = head.partition(":")
    given: dict[str, str] = {}
    for item in tail.split(",") if colon else ():
        key, eq, value = item.partition("=")
        if not eq or not _PLAIN.fullmatch(key) or not _PLAIN.fullmatch(value.replace(";", "x") or "="):
            raise _fail(text, f"{item!r} is no OPTION=VALUE; write {name}:OPTION=VALUE,... (values without , ( ) =).")
        if key in given:
            raise _fail(text, f"option {key!r} given twice; give each option once.")
        given[key] = value
    return name, given


def _typed(name: str, given: dict[str, Any]) -> dict[str, Any]:
    """``given`` with each value typed as ``name``'s options say (PolicyNameError on a wrong one)."""
    built = options_of(name, given)
    return {key: getattr(built, key) for key in given}


def is_recorded(text: str) -> bool:
    """Whether ``text`` is a name recorded before this grammar (a ``+``/``@`` option, ``:<price>``, ``learned:<stem>``,
    or a name of :data:`RECORDED_METHODS`)."""
    if text in RECORDED_METHODS or _MSHA.fullmatch(text):
        return True
    if "(" in text:
        return False
    name, _, after = text.split(OPTION_SEPARATOR)[0].split("@")[0].partition(":")
    unnamed = bool(after) and "=" not in after.split(",")[0]  # learned:<stem>, batch_assignment_value:<price_s>
    return OPTION_SEPARATOR in text or "@" in text or (unnamed and name in ("learned", VALUE_DISPATCHER))


def recorded_source(stem: str) -> str:
    """The checkpoint a recorded ``learned:<stem>`` flew: the shipped file ``<stem>.pt`` when the package has one
    (by file, not by :data:`~uamfleet.rl.checkpoint.PRETRAINED` name: ``berlin_fleet.pt`` is not
    ``pretrained("berlin_fleet")``), else the run ``runs/<stem>/best.pt``."""
    shipped = Path(str(resources.files("uamfleet") / "data" / "pretrained" / f"{stem}.pt"))
    return str(shipped) if shipped.is_file() else str(Path("runs") / stem / "best.pt")


def _dispatch_options(options: DispatchOptions) -> dict[str, Any]:
    """The registry's options of a recorded dispatcher's ``+`` options (those set)."""
    out: dict[str, Any] = {}
    if options.wait_weight:
        out["wait"] = options.wait_weight
    if options.assign_on_release:
        out["release"] = True
    if options.unassigned_price_s is not None:
        out["unassigned_price_s"] = options.unassigned_price_s
    if options.unassigned_guard_s is not None:
        out["unassigned_guard_s"] = options.unassigned_guard_s
    return out


def _recorded_dispatcher(text: str) -> Call:
    """The call of a recorded dispatcher ``NAME[:<price_s>][+OPTION...][@<value stem>]``."""
    head, at, stem = text.partition("@")
    base, dispatch = split_options(head)
    name, colon, price = base.partition(":")
    options = _dispatch_options(dispatch)
    if name != VALUE_DISPATCHER and (colon or at):
        raise _fail(text, f":<price_s> and @<value> belong to {VALUE_DISPATCHER}, not to {name!r}.")
    if colon:
        options["value_price_s"] = price
    if at:
        options["value"] = stem
    if name not in ("insertion", "batch_assignment", VALUE_DISPATCHER):
        raise _fail(text, f"+options belong to the schedule dispatchers, not to {name!r}; drop them.")
    return name, _typed(name, options)


def _recorded(text: str) -> Call:
    """The call of a recorded name (:func:`is_recorded`)."""
    if text in RECORDED_METHODS:
        return RECORDED_METHODS[text][0], dict(RECORDED_METHODS[text][1])
    msha = _MSHA.fullmatch(text)
    if msha:  # the paper table's learned variant: its checkpoint is the table's --checkpoints file
        return "learned", {}
    learned = _RECORDED_LEARNED.fullmatch(text)
    if learned:
        options: dict[str, Any] = {"source": recorded_source(learned.group(1))}
        if learned.group(2) is None:
            options["passenger_slots"] = "world"  # read every request of the instance, as the fleet benchmark did
        else:
            options["passenger_window"] = int(learned.group(2))
        return "learned", _typed("learned", options)
    if text.startswith("learned"):
        raise _fail(text, "a recorded learned name is learned:<stem>[+window<K>]; write learned:source=<file>.")
    return _recorded_dispatcher(text)


def parse(text: str) -> Call:
    """``(name, options)`` of a policy name in the grammar (module docstring) or a recorded alias; PolicyNameError
    (a ValueError) naming an unknown policy, option or value and what exists."""
    if not isinstance(text, str) or not text.strip():
        raise _fail(text, "name a policy, e.g. replan or guided(learned:source=berlin).")
    if text in LABELS:
        raise NoSuchPolicy(f"policy name {text!r}: a published figure's label ({', '.join(LABELS)}), not a policy; "
                           "name a policy instead.")  # fmt: skip
    if is_recorded(text):
        return _recorded(text)
    head, base = _split_base(text)
    name, given = _read_options(text, head)
    if base is not None:
        name = SEARCH_ALIAS.get(name, name)
        if entry(name).kind != "search":
            raise _fail(text, f"{name!r} is a {entry(name).kind}; only a search takes a base in parentheses.")
    options = _typed(name, given)
    if base is not None:
        options[BASE] = parse(base)
    return name, options


def format(name: str, options: dict[str, Any] | None = None) -> str:
    """The text of ``(name, options)`` in the grammar; the inverse of :func:`parse` (a search's ``base`` is a
    ``(name, options)`` pair)."""
    options = dict(options or {})
    base = options.pop(BASE, None)
    typed = _typed(name, options)
    items = []
    for key, value in typed.items():
        text = format_value(value)
        if not _PLAIN.fullmatch(text.replace(";", "x")):
            raise _fail(name, f"{key}={value!r} cannot be written in a name (no , ( ) = or spaces); pass it to make.")
        items.append(f"{key}={text}")
    out = name + (":" + ",".join(items) if items else "")
    if base is not None:
        if not (isinstance(base, tuple) and len(base) == 2):
            raise _fail(name, f"base={base!r} is no (name, options) pair; only such a base can be written.")
        out += f"({format(*base)})"
    return out


__all__ = [
    "LABELS",
    "RECORDED_METHODS",
    "SEARCH_ALIAS",
    "Call",
    "format",
    "is_recorded",
    "parse",
    "recorded_source",
]
