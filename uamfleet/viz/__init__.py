"""uamfleet.viz (see DESIGN.md)."""
