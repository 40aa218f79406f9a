"""LaCAM, side by side: the search (:mod:`.reference`), the loop's planner (:mod:`.planner`),
the compiled configuration generator (:mod:`.kernels`) and the footprint variant
(:mod:`.footprint`)."""
