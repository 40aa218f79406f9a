"""One-shot MAPF on plain grids (MovingAI instances): the solver (:mod:`.core`) and its guide
paths (:mod:`.scatter`, compiled in :mod:`.scatter_kernels`)."""
