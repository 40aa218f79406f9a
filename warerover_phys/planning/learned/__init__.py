"""The ``learned`` planner (:mod:`.planner`) and its numpy policy (:mod:`.policy`); the weights
ship in ``warerover_phys/planning/weights/``."""
