"""uamfleet.baselines (see DESIGN.md)."""
