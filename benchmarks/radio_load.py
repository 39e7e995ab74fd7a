"""Load / build times of the radio maps (the figures quoted in docs/benchmarks.md).

.venv/bin/python benchmarks/radio_load.py [--winprop PATH]
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path


from uamfleet.radio import packaged, read_winprop
from uamfleet.cli._common import run


@dataclass
class Args:
    winprop: Path = Path("../shared/data/berlin/berlin_UAM_SNIR_100.txt")
    """Berlin WinProp text file to time the parser on (skipped when missing)"""
    repeats: int = 3


def best_of(fn, repeats: int) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main(args: Args) -> None:
    rows = [
        ("Berlin, packaged npz", lambda: packaged._berlin()),
        ("Detroit estimate, packaged csv", lambda: packaged._detroit_estimate()),
        ("Detroit-like TR 36.777 map, built (1114 x 1114)", lambda: packaged._detroit_3gpp()),
    ]
    if args.winprop.is_file():
        rows.append((f"Berlin, WinProp text parse ({args.winprop.name})", lambda: read_winprop(args.winprop)))
    for name, fn in rows:
        print(f"{name:<55} {best_of(fn, args.repeats) * 1000:8.1f} ms (best of {args.repeats})")


if __name__ == "__main__":
    raise SystemExit(run(main, Args, None, "benchmarks/radio_load.py", __doc__))
