"""``python -m warerover_phys`` is the ``warerover`` command (:mod:`warerover_phys.entry`)."""

from .entry import main

main()
