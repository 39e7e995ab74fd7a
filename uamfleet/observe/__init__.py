"""What a policy reads of the simulator: the observation's spec (:mod:`~uamfleet.observe.spec`), the observer that
writes it (:mod:`~uamfleet.observe.observer`), its compiled components (the always-on fields in
:mod:`~uamfleet.observe.basic`, the stop features in :mod:`~uamfleet.observe.stops`, the heading look-ahead in
:mod:`~uamfleet.observe.lookahead`) with the tour planner and move geometry they read (:mod:`~uamfleet.observe.tours`,
:mod:`~uamfleet.observe.moves`), and the passenger window (:mod:`~uamfleet.observe.window`). It sits on the
simulator (:mod:`uamfleet.sim`) and below the faces (:mod:`uamfleet.env`)."""
