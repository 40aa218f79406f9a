"""The ``warerover`` console script (and ``python -m warerover_phys``).

``solve`` with plainly well-formed arguments starts without the full command line (typer,
rich, the scenario models): :func:`warerover_phys.cli.solve.fast_main`, so that a one-shot
solve is timed as a user waits for it; everything else, and ``solve`` with anything it does
not read, goes to :func:`warerover_phys.cli.main`. This module imports nothing at its top.
"""

__all__ = ["main"]


def main() -> None:
    import sys

    if len(sys.argv) > 1 and sys.argv[1] == "solve":
        from .solve import fast_main

        fast_main(sys.argv[1:])  # exits when it ran the command

    from .commands import main as cli_main

    cli_main()
