"""``python -m warerover_phys`` is the ``warerover`` command."""

from .cli import main

main()
