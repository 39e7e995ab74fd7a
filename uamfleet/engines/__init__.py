"""Adapters for the multi-agent engines a user moves to (docs/scaling.md "Beyond torchrun").

- :mod:`uamfleet.engines.rllib`: RLlib's PPO on any scenario: the observation flattened beside its
  ``action_mask`` (the form RLlib's action-masking module reads), one shared policy for every taxi.
- :mod:`uamfleet.engines.torchrl`: TorchRL's PettingZoo wrapper, a masked categorical policy shared over the
  taxis (one group), and a collector.

Neither engine is a dependency of uamfleet: each module imports its engine only inside the functions that need it,
so importing them costs nothing; a function that needs a missing engine raises :class:`EngineMissingError` (an
ImportError) saying how to install it. ``bash scripts/engines.sh`` installs both into ``.venv-engines`` and runs their
end-to-end tests (one PPO iteration, one collector batch).
"""

from __future__ import annotations

import importlib

INSTALL = {
    "rllib": "pip install 'ray[rllib]' into a venv of its own (ray[rllib] pins an older gymnasium than uamfleet's; "
    "bash scripts/engines.sh --setup makes one)",
    "torchrl": "pip install 'uamfleet[torchrl]'",
}
"""How to install each engine: TorchRL is uamfleet's extra ``torchrl``; RLlib is no extra (its gymnasium pin)."""


class EngineMissingError(ImportError):
    """An engine's package is not installed; the message says how to install it."""


def require(engine: str, *modules: str) -> None:
    """Import ``modules`` (the packages of ``engine``, a key of :data:`INSTALL`), or raise one
    :class:`EngineMissingError` naming the engine, the missing module and the install command."""
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as err:
            missing = err.name or module
            raise EngineMissingError(
                f"uamfleet.engines.{engine} needs {module}, which is not installed (no module {missing!r}): "
                f"{INSTALL[engine]}.",
                name=missing,
            ) from None


__all__ = ["INSTALL", "EngineMissingError", "require"]
