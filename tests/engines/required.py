"""The engine tests need RLlib or TorchRL, which the default .venv lacks: they are skipped there, and
``bash scripts/engines.sh`` runs them in the engines venv with UAMFLEET_REQUIRE_ENGINES=1, where a missing engine
is an error instead of a skip (so the CI step cannot pass by skipping)."""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest


def require(module: str) -> ModuleType:
    """``module`` imported; skipped when it is absent, unless UAMFLEET_REQUIRE_ENGINES=1 (then it fails)."""
    if os.environ.get("UAMFLEET_REQUIRE_ENGINES") == "1":
        return importlib.import_module(module)
    return pytest.importorskip(module)
