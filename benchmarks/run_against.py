"""Run a benchmark script against another checkout of the package (e.g. the base of a branch), for before/after
figures in one session: the editable install's finder is dropped and the checkout put first on the path.

    git archive f544538 | tar -x -C /tmp/before
    .venv/bin/python benchmarks/run_against.py /tmp/before benchmarks/env_throughput.py

The script's own numba functions must not be cached (``cache=True``): a cached copy keeps the package functions
it was compiled against, whichever checkout runs it.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path


def main() -> None:
    if len(sys.argv) < 3 or not (Path(sys.argv[1]) / "uamfleet" / "__init__.py").is_file():
        print("usage: run_against.py CHECKOUT SCRIPT [ARGS...]; CHECKOUT: a checkout with uamfleet/", file=sys.stderr)
        sys.exit(2)
    checkout, script = sys.argv[1], sys.argv[2]
    sys.meta_path[:] = [finder for finder in sys.meta_path if "editable" not in repr(finder).lower()]
    sys.path.insert(0, checkout)
    sys.argv = sys.argv[2:]
    runpy.run_path(script, run_name="__main__")


if __name__ == "__main__":
    main()
