"""Who asks for a ride: :class:`Request` (one fixed request), :func:`as_requests` and :class:`DemandConfig` (the
random demand model). Parts of :class:`uamfleet.config.EnvConfig`, which re-exports them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from uamfleet.checks import MAX_PASSENGERS, ConfigError, check_integer, check_number, check_point, check_sequence


@dataclass(frozen=True)
class Request:
    """One ride request: visible (and pickable on the following steps) from ``release_step`` on."""

    release_step: int
    origin_m: tuple[float, float]
    destination_m: tuple[float, float]

    def __post_init__(self) -> None:
        release = check_integer("Request release_step", self.release_step, 0, fix=" (steps since reset)")
        object.__setattr__(self, "release_step", release)
        for name in ("origin_m", "destination_m"):
            object.__setattr__(self, name, check_point(f"Request {name}", getattr(self, name)))
        if self.origin_m == self.destination_m:
            raise ConfigError(
                f"Request origin_m == destination_m == {self.origin_m}: a ride needs two different places; "
                "drop the request or move one end."
            )


def as_requests(items: Sequence[Any]) -> tuple[Request, ...]:
    """Requests from :class:`Request` objects or ``(release_step, (ox, oy), (dx, dy))`` tuples."""
    out = []
    for item in check_sequence("requests", items):
        if isinstance(item, Request):
            out.append(item)
        elif isinstance(item, (tuple, list)) and len(item) == 3:
            out.append(Request(item[0], item[1], item[2]))
        else:
            raise ConfigError(f"Request {item!r} must be a Request or (release_step, origin_xy, destination_xy).")
    return tuple(out)


ARRIVALS: tuple[str, ...] = ("poisson", "uniform")
"""Values of ``DemandConfig.arrivals``."""


@dataclass(frozen=True)
class DemandConfig:
    """Random demand: Poisson arrivals of ride requests.

    ``arrivals="poisson"``: ``num_initial`` requests are released at step 0; afterwards requests arrive with
    ``rate_per_step`` until ``horizon_steps`` (at most ``max_requests`` in all). ``arrivals="uniform"``: the
    number of requests is drawn uniformly from ``min_requests`` ... ``max_requests``; ``num_initial`` of them
    (at least one) are released at step 0 and the others at steps drawn uniformly from 0 ... ``horizon_steps``
    (the held-out instances of :mod:`uamfleet.instances` are drawn this way). Origins and destinations are drawn
    on feasible blocks (or from ``vertiports`` when given), at least ``min_trip_m`` apart.
    """

    num_initial: int = 3
    rate_per_step: float = 0.05
    horizon_steps: int = 60
    max_requests: int = 8
    min_trip_m: float = 500.0
    vertiports: tuple[tuple[float, float], ...] = ()
    arrivals: str = "poisson"
    min_requests: int = 1  # arrivals="uniform" only

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("max_requests", check_integer("DemandConfig.max_requests", self.max_requests, 1, MAX_PASSENGERS))
        put("num_initial", check_integer("DemandConfig.num_initial", self.num_initial, 0, self.max_requests))
        put("rate_per_step", check_number("DemandConfig.rate_per_step", self.rate_per_step, minimum=0))
        put("horizon_steps", check_integer("DemandConfig.horizon_steps", self.horizon_steps, 0))
        put("min_trip_m", check_number("DemandConfig.min_trip_m", self.min_trip_m, minimum=0))
        if self.arrivals not in ARRIVALS:
            raise ConfigError(f"DemandConfig.arrivals={self.arrivals!r} is unknown; use one of {ARRIVALS}.")
        put("min_requests", check_integer("DemandConfig.min_requests", self.min_requests, 1, self.max_requests))
        ports = tuple(
            check_point(f"DemandConfig.vertiports[{i}]", p)
            for i, p in enumerate(check_sequence("DemandConfig.vertiports", self.vertiports))
        )
        if len(ports) == 1:
            raise ConfigError("DemandConfig.vertiports needs at least 2 sites (origin != destination), got 1.")
        if len(set(ports)) != len(ports):
            raise ConfigError(
                f"DemandConfig.vertiports={ports} lists a site twice: a ride between them would not move; "
                "give each site once."
            )
        put("vertiports", ports)
