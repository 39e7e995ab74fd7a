"""The model zoo's former home: :func:`pretrained` and :func:`export_policy` live in :mod:`uamfleet.policies.learned`
(this module re-exports them for one release)."""

from __future__ import annotations

from uamfleet.policies.learned import PRETRAINED, export_policy, pretrained, pretrained_path

__all__ = ["PRETRAINED", "export_policy", "pretrained", "pretrained_path"]
