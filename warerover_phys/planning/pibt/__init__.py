"""PIBT, side by side: the Python reference step (:mod:`.reference`), the loop's planner
(:mod:`.planner`), the compiled steps (:mod:`.kernels`, :mod:`.compiled`), the heading variant
(:mod:`.heading`) and the footprint variant for ``k x k`` AGVs (:mod:`.footprint`)."""
