"""One registry of policies: planners, fleet dispatchers, learned policies and search at decision time, by name.

    from uamfleet import policies
    policies.available()                                  # {name: (kind, OptionsClass)}
    planner = policies.make("replan", beam=32)
    search = policies.make(*policies.parse("guided:top_k=4(learned:source=berlin)"))

The string form (:mod:`uamfleet.policies.names`) is the one the command lines take; the names the benchmarks
recorded before it read as aliases.
"""

from __future__ import annotations

from typing import Any

from uamfleet.policies import learned as _learned
from uamfleet.policies import planners as _planners
from uamfleet.policies import search as _search
from uamfleet.policies.names import format, is_recorded, parse
from uamfleet.policies.planners import ONE_FLIGHT_OPTIONS, make_flown
from uamfleet.policies.registry import KINDS, NoSuchPolicy, PolicyNameError, available, make, register


def make_named(text: str, **overrides: Any) -> Any:
    """The policy a name in the string form (or a recorded alias) names, ``overrides`` on top of its options."""
    name, options = parse(text)
    return make(name, **{**options, **overrides})


def kind_of(text: str) -> str | None:
    """The registry's kind (:data:`KINDS`) of the policy a name in the string form names; None for a name of no
    policy (unknown, or a published figure's label). A known policy with a bad option raises
    :class:`PolicyNameError` naming it."""
    try:
        return available()[parse(text)[0]][0]
    except NoSuchPolicy:
        return None


_REGISTERED = (_learned, _planners, _search)  # importing them registers their policies

__all__ = [
    "KINDS",
    "ONE_FLIGHT_OPTIONS",
    "PolicyNameError",
    "available",
    "format",
    "is_recorded",
    "kind_of",
    "make",
    "make_flown",
    "make_named",
    "parse",
    "register",
]
