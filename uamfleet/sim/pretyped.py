"""A pre-typed entry into a compiled kernel: numba's dispatcher types every argument on every call, a NamedTuple
(:class:`~uamfleet.types.FleetState`, :class:`~uamfleet.sim.arrays.WorldArrays`) field by field in Python, about
10 µs per call, which is most of a one-taxi step (docs/benchmarks.md, "The environment"). A
:class:`PreTyped` kernel looks the machine code of its arguments' types up once and calls it directly while the
same NamedTuples come back, which they do every step of an env: the state is updated in place, the world's arrays
never change.
"""

from __future__ import annotations

from typing import Any


class PreTyped:
    """``kernel`` (a numba dispatcher) called through the compiled entry of the types of its last arguments.

    The first two arguments (the NamedTuples) are checked by identity: the same objects hold the same arrays, so
    their types cannot have changed. Every other argument must have the same type on every call (the callers pass
    freshly allocated C-contiguous arrays of fixed dtypes and plain scalars); new NamedTuples (another env's state,
    a reset's copy) go through the dispatcher once and are looked up again."""

    __slots__ = ("_entry", "_first", "_second", "kernel")

    def __init__(self, kernel: Any) -> None:
        self.kernel = kernel
        self._first: Any = None
        self._second: Any = None
        self._entry: Any = None

    def __call__(self, first: Any, second: Any, *rest: Any) -> Any:
        if first is self._first and second is self._second:
            return self._entry(first, second, *rest)
        result = self.kernel(first, second, *rest)  # types (and at first compiles) as usual
        types = tuple(self.kernel.typeof_pyval(a) for a in (first, second, *rest))
        self._entry = self.kernel.overloads[types].entry_point
        self._first, self._second = first, second
        return result
