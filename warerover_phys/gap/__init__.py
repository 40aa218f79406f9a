"""The sim-to-real gap: :mod:`.core` (one scenario and seed, open or closed loop),
:mod:`.open_loop` (a fixed plan executed on physics, lost time by cause), :mod:`.ideal_plan`
(the plan of the ideal run), :mod:`.stats` (many seeds) and :mod:`.plots` (pictures).
The command is :mod:`warerover_phys.cli.gap`."""
