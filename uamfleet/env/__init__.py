"""The faces of the simulator with its observer: the batched environment (core), its PettingZoo face, the mixture
of worlds and the worker processes."""
