"""``warerover solve``: the one-shot MAPF command's body, and its start-up fast path.

A one-shot solve is timed as the user waits for it, from the process start: the interpreter
and its imports count. The full command line (typer, rich, and through the other commands
the scenario models, pydantic, YAML) costs about half a second of CPU before any work is
done, so ``python -m warerover_phys solve ...`` (:mod:`warerover_phys.__main__`) first tries
:func:`fast_main`: it reads the arguments itself when they are plainly well formed (the
options below, their values plain numbers) and runs :func:`run_solve` importing numpy,
scipy's graph search and the modules the solve needs. Anything else (``--help``, an unknown
or misspelt option, a value typer would refuse or convert otherwise) goes to the typer
command (:func:`warerover_phys.cli.solve`), which runs the same :func:`run_solve`, so both
give the same output and exit codes. This module imports nothing heavy at its top.
"""

from __future__ import annotations

import contextlib
import json
import re
import sys
import time
from pathlib import Path

__all__ = ["run_solve", "parse_solve_args", "fast_main", "SOLVE_RESERVE",
           "numba_without_blas_probe"]

SOLVE_RESERVE = (0.03, 0.5)
"""Of ``solve --time-limit``: a share and seconds kept for validating and writing the plan
and for the interpreter's exit."""
_ENTERED: tuple[float, float] | None = None
"""(monotonic time, process age in s) when the command started as its own process: its
start-up counts against ``solve --time-limit``; None when the command is called in a
longer-lived process (tests, notebooks)."""


def process_age_s() -> float:
    """Seconds since this process started (Linux ``/proc``; 0 where it cannot be read)."""
    import os

    try:
        with open("/proc/self/stat", encoding="ascii") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])  # field 22: starttime
        with open("/proc/uptime", encoding="ascii") as f:
            up = float(f.read().split()[0])
        return max(0.0, up - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return 0.0


def mark_entered() -> None:
    """Note that the command is this process (its age counts against the time limit)."""
    global _ENTERED
    _ENTERED = (time.monotonic(), process_age_s())


def command_age_s() -> float:
    """Seconds since the process started, if this command is the process; else 0."""
    if _ENTERED is None:
        return 0.0
    return _ENTERED[1] + time.monotonic() - _ENTERED[0]


def numba_without_blas_probe() -> bool:
    """Load numba's numpy support without its BLAS probe; True if it was skipped.

    The compiled guide search and LaCAM steps (from ``NUMBA_MIN_AGENTS`` agents) load from
    numba's cache, which first imports ``numba.np.arraymath``; that module asks once whether
    BLAS is there by importing ``scipy.linalg``, whose array-API layer imports most of
    numpy's submodules (f2py, testing, ma): 0.35-0.7 s of CPU, a fifth of a 700-agent solve.
    None of the compiled code uses BLAS (no ``np.dot``, no linear algebra). So, in the
    command's own process only (:func:`run_solve` when :func:`mark_entered` was called), the
    probe's answer is "no BLAS": numba's own loop is used should a later compile in this
    process need ``np.convolve`` or ``np.correlate``, and ``np.dot`` / ``np.linalg`` would still
    import scipy when compiled (the probe function is restored at once). A numba without
    these names (another version) is left as it is."""
    if "numba.np.arraymath" in sys.modules:
        return False
    try:
        import numba.np.linalg as nplinalg
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    probe = getattr(nplinalg, "ensure_blas", None)
    if probe is None:  # pragma: no cover - another numba
        return False

    def no_blas() -> None:
        raise ImportError("BLAS probe skipped by warerover solve")

    nplinalg.ensure_blas = no_blas
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        nplinalg.ensure_blas = probe
    return True


@contextlib.contextmanager
def _quiet_interrupt():
    """While the search runs in the command's own process: Ctrl-C ends the process at once
    with exit code 130 and one line, as ``run`` does. Python's own KeyboardInterrupt cannot
    be used there: raised inside the compiled (numba) search it surfaces as a SystemError
    with two tracebacks. Nothing has been written yet (the plan file comes after)."""
    import signal
    import threading

    if _ENTERED is None or threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame) -> None:
        import os

        os.write(2, b"interrupted\n")
        os._exit(130)

    old = signal.signal(signal.SIGINT, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _distinct_ends(scen, source: str) -> None:
    """Refuse two agents on one start (or one goal): no plan exists, and the search would
    look for one until its time limit."""
    from ..errors import ScenarioError

    for what in ("start", "goal"):
        seen: dict[tuple[int, int], int] = {}
        for i, a in enumerate(scen):
            cell = getattr(a, what)
            if cell in seen:
                raise ScenarioError(f"agents {seen[cell]} and {i} have the same {what} "
                                    f"(row {cell[0]}, col {cell[1]}): no plan exists",
                                    file=source, field=f"agent {i}")
            seen[cell] = i


def _echo(text: str, err: bool = False) -> None:
    stream = sys.stderr if err else sys.stdout
    stream.write(text + "\n")
    stream.flush()


def run_solve(map_file: Path, scen_file: Path, agents: int = 100, planner: str = "lacam",
              time_limit: float = 60.0, seed: int = 0, json_out: bool = False,
              out: Path | None = None, guide: bool = True, refine: bool = False, *,
              fail) -> int:
    """Solve a one-shot MovingAI instance, validate the plan, write it (``out``) and print
    its figures; returns the exit code (0 solved, 1 not). Bad input goes to ``fail(err)``,
    which must not return (prints one line, exits 2)."""
    from ..errors import WareroverError
    from ..inputs import check_output_file, check_seed
    from ..planning.oneshot.core import solve as solve_instance
    from ..planning.oneshot.core import write_plan
    from ..problems.movingai import read_map, read_scen
    from ..validate import validate_cell_paths

    try:
        if agents < 1:
            raise WareroverError(f"--agents: must be at least 1 (got {agents})")
        check_seed(seed)
        if out is not None:
            check_output_file(out)
        if not 0 < time_limit < float("inf"):
            raise WareroverError(f"--time-limit: must be positive and finite (got {time_limit})")
        grid = read_map(map_file)
        scen = read_scen(scen_file, agents, grid)
        _distinct_ends(scen, str(scen_file))
        # The limit covers what the user waits for: start-up and reading so far, the
        # validation, the plan file and the exit after solving (SOLVE_RESERVE).
        share, fixed = SOLVE_RESERVE
        budget = max(0.05 * time_limit, time_limit * (1 - share) - fixed - command_age_s())

        def improved(seconds: float, soc: int) -> None:
            if not json_out:
                _echo(f"refine: {seconds:7.2f} s  sum of costs {soc}", err=True)

        result = _search(solve_instance, grid, scen, agents, planner, budget, seed, guide,
                         refine, improved)
        conflicts = []
        if result.success:
            conflicts = validate_cell_paths(result.paths, grid.obstacles)
            ends_ok = all(p[0] == a.start and p[-1] == a.goal
                          for p, a in zip(result.paths, scen, strict=True))
            if conflicts or not ends_ok:
                result.success = False
        if out is not None and result.success:
            write_plan(out, result, map_file=map_file.name, scen_file=scen_file.name)
    except WareroverError as err:
        fail(err)
    except OSError as err:
        fail(WareroverError(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}"))
    figures = _solve_figures(map_file, scen_file, agents, planner, result, conflicts, refine)
    if json_out:
        _echo(json.dumps(figures, indent=2))
    else:
        for k, v in figures.items():
            _echo(f"{k:>13}: {v}")
    return 0 if result.success else 1


def _search(solve_instance, grid, scen, agents: int, planner: str, budget: float, seed: int,
            guide: bool, refine: bool, improved):
    """The one-shot search of :func:`run_solve` (``solve_instance``: its solver, loaded
    first; garbage collection paused)."""
    if _ENTERED is not None and planner in ("lacam", "pibt"):
        from ..planning.oneshot.scatter import NUMBA_MIN_AGENTS

        if agents >= NUMBA_MIN_AGENTS:  # the compiled kernels may load
            numba_without_blas_probe()
    # The search makes many small objects and no cyclic garbage to speak of: the
    # collector's passes over the objects loaded so far (frozen) and its frequent young
    # passes are skipped (LaCAM's CPU -10% at 700 agents); restored afterwards.
    import gc

    thresholds = gc.get_threshold()
    gc.freeze()
    gc.set_threshold(50_000, 50, 100)
    try:
        with _quiet_interrupt():
            result = solve_instance(grid.obstacles, [a.start for a in scen],
                                    [a.goal for a in scen], planner=planner,
                                    time_limit_s=budget, seed=seed, guide=guide,
                                    refine=refine, on_improve=improved)
    finally:
        gc.set_threshold(*thresholds)
        gc.unfreeze()
    return result


def _solve_figures(map_file: Path, scen_file: Path, agents: int, planner: str, result,
                   conflicts: list, refine: bool) -> dict:
    """What :func:`run_solve` prints (or writes as JSON)."""
    figures = {"map": map_file.name, "scen": scen_file.name, "agents": agents,
               "planner": planner, "success": result.success,
               "sum_of_costs": result.sum_of_costs, "makespan": result.makespan,
               "lower_bound": result.lower_bound,
               "soc_over_lb": round(result.soc_ratio, 4) if result.success else None,
               "wall_s": round(result.wall_s, 4), "conflicts": len(conflicts)}
    if refine:
        ref = result.stats.get("refine", {})
        figures.update(first_sum_of_costs=ref.get("first_soc"),
                       refine_iterations=ref.get("iterations"),
                       refine_improvements=ref.get("improvements"))
    return figures


# ----------------------------------------------------------------------------- fast path

_INT = re.compile(r"-?[0-9]+\Z")
_FLOAT = re.compile(r"-?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][-+]?[0-9]+)?\Z")
_VALUED = {"--agents": ("agents", int, _INT), "--planner": ("planner", str, None),
           "--time-limit": ("time_limit", float, _FLOAT), "--seed": ("seed", int, _INT),
           "--out": ("out", Path, None)}
_FLAGS = {"--json": ("json_out", True), "--guide": ("guide", True),
          "--no-guide": ("guide", False), "--refine": ("refine", True)}


def parse_solve_args(argv: list[str]) -> dict | None:
    """The keyword arguments of :func:`run_solve` from ``argv`` (after ``solve``), or None
    unless every token is plainly one the typer command reads the same way: the two
    arguments, the options above (``--opt VALUE`` or ``--opt=VALUE``; a later one wins, as
    in typer), numbers written plainly, no empty values."""
    kwargs: dict = {}
    positional: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        i += 1
        if not token.startswith("-"):
            if not token:
                return None
            positional.append(token)
            continue
        name, eq, value = token.partition("=")
        if name in _FLAGS and not eq:
            key, flag = _FLAGS[name]
            kwargs[key] = flag
            continue
        if name not in _VALUED:
            return None  # --help, -h, --, an unknown or abbreviated option: typer's to answer
        if not eq:
            if i >= len(argv):
                return None
            value = argv[i]
            i += 1
        key, kind, pattern = _VALUED[name]
        if not value or (pattern is not None and not pattern.match(value)):
            return None
        kwargs[key] = kind(value)
    if len(positional) != 2:
        return None
    kwargs["map_file"], kwargs["scen_file"] = Path(positional[0]), Path(positional[1])
    return kwargs


def _fail(err: Exception):
    """As the typer command fails: one line on stderr (rich), exit code 2."""
    import typer

    from ..util.console import fail

    try:
        fail(err)
    except typer.Exit as exit_:
        sys.exit(exit_.exit_code)


def fast_main(argv: list[str]) -> None:
    """Run ``solve`` from ``argv`` (``["solve", ...]``) and exit, if :func:`parse_solve_args`
    reads it; else return (the caller runs the full command line)."""
    if not argv or argv[0] != "solve":
        return
    kwargs = parse_solve_args(argv[1:])
    if kwargs is None:
        return
    mark_entered()
    try:
        code = run_solve(**kwargs, fail=_fail)
    except KeyboardInterrupt:
        from ..util.console import err_console

        err_console.print("interrupted")
        sys.exit(130)
    sys.exit(code)
