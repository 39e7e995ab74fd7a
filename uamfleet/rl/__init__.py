"""uamfleet.rl (see DESIGN.md)."""
