"""Adapters for the multi-agent engines a user moves to (docs/scaling.md "Beyond torchrun").

- :mod:`uamfleet.engines.rllib`: RLlib's PPO on any scenario: the observation flattened beside its
  ``action_mask`` (the form RLlib's action-masking module reads), one shared policy for every taxi.
- :mod:`uamfleet.engines.torchrl`: TorchRL's PettingZoo wrapper, a masked categorical policy shared over the
  taxis (one group), and a collector.

Neither engine is a dependency of uamfleet: each module imports its engine only inside the functions that need it,
so importing them costs nothing. ``bash scripts/engines.sh`` installs both into ``.venv-engines`` and runs their
end-to-end tests (one PPO iteration, one collector batch).
"""
