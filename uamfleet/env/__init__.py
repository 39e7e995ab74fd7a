"""The batched fleet environment (core) and its PettingZoo face."""
