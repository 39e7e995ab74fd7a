"""uamfleet.viz: pictures of radio maps and fleets; no simulation logic (everything drawn comes from a radio
map, a recorded trajectory or a state handed in).

- :mod:`uamfleet.viz.figures`: matplotlib figures (routes over the radio map, connectivity, env frames).
- :mod:`uamfleet.viz.curves`: learning curves of training runs (greedy TD and PR against agent-steps, from
  progress.csv; several seeds with their median and range).
- :mod:`uamfleet.viz.strip`: SINR along a flown path over time; who served whom, from the recorded events.
- :mod:`uamfleet.viz.meshcat_view`: :class:`~uamfleet.viz.meshcat_view.FleetViewer`, the 3-D meshcat scene
  (live in the browser, or one offline HTML page), with its rooms :mod:`~uamfleet.viz.meshcat_server` (the
  meshcat import, the server process), :mod:`~uamfleet.viz.textures` (map texture, labels, legend) and
  :mod:`~uamfleet.viz.page` (the offline page). meshcat is imported only when a viewer is made.
- :mod:`uamfleet.viz.colours`: the palette every view shares.
- :mod:`uamfleet.viz.render`: the renderers of the PettingZoo env's ``render_mode`` values.

Nothing is imported eagerly here: ``import uamfleet.viz`` costs nothing.
"""
