"""The simulator: the world (map, stops, rules), the state's generator, the step's motion and dynamics, and the
reward. It reads no observation: the observers and the faces (:mod:`uamfleet.env`) sit above it."""
