"""``python -m warerover_phys`` is the ``warerover`` command (:mod:`warerover_phys.cli.entry`)."""

from .cli.entry import main

main()
