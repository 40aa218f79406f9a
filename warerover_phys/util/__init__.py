"""Small utilities every part shares: whole-or-absent outputs (:mod:`.atomic`), YAML with
limits (:mod:`.safe_yaml`), the error console (:mod:`.console`), the garbage collector in long
loops (:mod:`.gc_tuning`) and output-path checks (:mod:`.media`)."""
