"""Evaluation command lines (python -m eval.<name>)."""
