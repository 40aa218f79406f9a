"""Anytime refinement of one-shot plans by large-neighbourhood search: the LNS
(:mod:`.lns`) and its compiled single-agent search (:mod:`.kernels`)."""
