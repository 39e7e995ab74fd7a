"""uamfleet.viz: pictures of radio maps and fleets; no simulation logic (see DESIGN.md).

- :mod:`uamfleet.viz.figures`: matplotlib figures (routes over the radio map, connectivity, env frames).
- :mod:`uamfleet.viz.strip`: SINR along a flown path over time; who served whom, from the recorded events.
- :mod:`uamfleet.viz.meshcat_view`: :class:`~uamfleet.viz.meshcat_view.FleetViewer`, the 3-D meshcat scene
  (live in the browser, or one offline HTML page). meshcat is imported only when a viewer is made.

Nothing is imported eagerly here: ``import uamfleet.viz`` costs nothing.
"""
