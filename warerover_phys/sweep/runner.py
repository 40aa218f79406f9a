"""Run every episode of a sweep once: a local process pool, or Ray.

The parent process alone writes the results file; workers run one episode per task and
return its row. An episode that raises becomes a ``status: failed`` row with its error and
traceback; a worker process that dies (segfault, out of memory) is retried alone once, and
recorded as failed if it dies alone too. Re-running the same sweep into the same folder runs
only the episodes without a row.

>>> from warerover_phys.sweep import load_sweep, run_sweep  # doctest: +SKIP
>>> run_sweep(load_sweep("tools/reproduce_table1.yaml"), "runs/table1", workers=2)  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import logging
import multiprocessing as mp
import os
import signal
import socket
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import Scenario
from ..errors import ScenarioError, WareroverError
from .lock import sweep_lock
from .results import RESULTS_NAME, ResultsFile
from .spec import Episode, SweepSpec, compile_scenarios, expand

__all__ = ["Task", "SweepSummary", "run_task", "run_sweep", "plan_sweep", "pool_map",
           "run_pool", "run_ray", "SPEC_NAME", "write_spec_json", "row_sink", "dispatch"]

log = logging.getLogger(__name__)

SPEC_NAME = "sweep.json"
"""The sweep's spec as last run, kept next to the results (the report reads it)."""


@dataclass(frozen=True)
class Task:
    """What a worker needs to run one episode (picklable, no files needed)."""

    key: str
    label: str
    file: str
    overrides: tuple[tuple[str, Any], ...]
    variant: tuple[tuple[str, Any], ...]
    seed: int
    scenario: Scenario
    sys_path: tuple[str, ...] = ()


@dataclass
class SweepSummary:
    total: int
    """Episodes in the sweep."""
    done_before: int
    """Episodes that already had a row when this run started."""
    ran: int = 0
    failed: int = 0
    """Episodes of this run recorded as failed."""
    failed_total: int = 0
    """Failed rows of the sweep in the results file after this run."""
    wall_s: float = 0.0
    out_dir: Path = field(default_factory=Path)

    @property
    def results(self) -> Path:
        return self.out_dir / RESULTS_NAME

    @property
    def left(self) -> int:
        """Episodes (cells) still without a row: a run stopped at its deadline."""
        return self.total - self.done_before - self.ran


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def _row(task: Task, status: str, **extra: Any) -> dict[str, Any]:
    sc = task.scenario
    return {"key": task.key, "scenario": task.label, "file": task.file,
            "overrides": dict(task.overrides), "variant": dict(task.variant), "seed": task.seed,
            "scheduler": sc.scheduler.name, "planner": sc.planner.name,
            "executor": sc.executor.name, "pattern": sc.orders.pattern, "status": status,
            "metrics": None, "error": None, "traceback": None, "host": socket.gethostname(),
            "pid": os.getpid(), "finished": _now(), **extra}


def failed_row(task: Task, error: str, tb: str | None = None) -> dict[str, Any]:
    """The row of an episode that did not finish."""
    return _row(task, "failed", error=error, traceback=tb)


def run_task(task: Task) -> dict[str, Any]:
    """Run one episode; never raises for an error of the episode (it becomes the row)."""
    from ..sim import run_episode

    for extra in reversed(task.sys_path):
        if extra not in sys.path:
            sys.path.insert(0, extra)
    t0 = time.perf_counter()
    try:
        metrics = run_episode(task.scenario, seed=task.seed).metrics
    except Exception as err:  # noqa: BLE001 - every episode error is recorded, not raised
        if isinstance(err, ScenarioError) and err.__cause__ is not None:
            err = err.__cause__                  # a plug-in's own error, as it raised it
        elif isinstance(err, ScenarioError):
            err.with_file(task.file)             # name the scenario file, not <scenario>
        tb = "".join(traceback.format_exception(err)[-12:])
        return {**failed_row(task, f"{type(err).__name__}: {err}", tb),
                "elapsed_s": time.perf_counter() - t0}
    return {**_row(task, "ok", metrics=metrics), "elapsed_s": time.perf_counter() - t0}


# ------------------------------------------------------------------------------- planning


def plan_sweep(spec: SweepSpec, out_dir: str | Path, *, retry_failed: bool = False,
               ) -> tuple[list[Task], SweepSummary, ResultsFile]:
    """Validate the sweep, read what ``out_dir`` holds, and return the tasks still to run."""
    out_dir = Path(out_dir)
    episodes = expand(spec)
    results = ResultsFile(out_dir / RESULTS_NAME)
    rows = results.load()
    keys = {ep.key for ep in episodes}
    if len(keys) != len(episodes):
        raise WareroverError(f"{spec.source}: two episodes of the sweep have the same key")
    if retry_failed:
        rows = results.drop_failed(rows, keys)[0]
    todo = [ep for ep in episodes if ep.key not in rows]
    scenarios = compile_scenarios(spec, todo)
    paths = spec.plugin_paths()
    tasks = [_task(spec, ep, scenarios[ep.combo], paths) for ep in todo]
    summary = SweepSummary(total=len(episodes), done_before=len(episodes) - len(todo),
                           failed_total=sum(1 for k, r in rows.items()
                                            if k in keys and r.get("status") != "ok"),
                           out_dir=out_dir)
    return tasks, summary, results


def _task(spec: SweepSpec, ep: Episode, scenario: Scenario, paths: tuple[str, ...]) -> Task:
    return Task(key=ep.key, label=ep.label, file=spec.scenarios[ep.label].file,
                overrides=ep.overrides, variant=ep.variant, seed=ep.seed, scenario=scenario,
                sys_path=paths)


def write_spec_json(spec: Any, out_dir: Path, name: str = SPEC_NAME) -> None:
    """Keep ``spec`` (a pydantic model with a ``source``) as ``out_dir/name``, written to a
    temporary file and renamed (a sweep's ``sweep.json``, a study's ``study.json``)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    data = {**spec.model_dump(mode="json"), "source": spec.source}
    tmp = out_dir / (name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, out_dir / name)


def row_sink(results: ResultsFile, summary: SweepSummary,
             on_row: Callable[[dict[str, Any]], None] | None) -> Callable[[dict[str, Any]], None]:
    """What takes each finished row: appended to ``results``, counted in ``summary`` (ran,
    failed: any status but ``ok``), handed to ``on_row``."""

    def sink(row: dict[str, Any]) -> None:
        results.append(row)
        summary.ran += 1
        if row["status"] != "ok":
            summary.failed += 1
            summary.failed_total += 1
        if on_row is not None:
            on_row(row)

    return sink


def dispatch(tasks: list[Any], ray_address: str | None, workers: int,
             sink: Callable[[Any], None], **kw: Any) -> None:
    """Run ``tasks`` on Ray (``ray_address``) or the local process pool (``kw``: ``fn``,
    ``fail`` of :func:`run_pool`)."""
    if tasks and ray_address is not None:
        run_ray(tasks, ray_address, workers, sink, **kw)
    elif tasks:
        run_pool(tasks, workers, sink, **kw)


def run_sweep(spec: SweepSpec, out_dir: str | Path, *, workers: int | None = None,
              ray_address: str | None = None, retry_failed: bool = False,
              on_start: Callable[[SweepSummary, int], None] | None = None,
              on_row: Callable[[dict[str, Any]], None] | None = None) -> SweepSummary:
    """Run the episodes of ``spec`` that ``out_dir`` has no row for.

    ``workers``: local processes (default: CPU count); ``ray_address``: run on Ray instead
    (``auto``, ``local`` or a cluster address; a Ray already initialised in this process is
    used as it is). ``on_start(summary, to_run)`` and ``on_row(row)`` drive a progress display.
    Raises :class:`KeyboardInterrupt` through (what finished is on disk); SIGTERM does the
    same. Holds ``out_dir``'s sweep lock (:mod:`.lock`): a second sweep on the same folder
    raises a :class:`WareroverError` naming the holder.
    """
    with sweep_lock(out_dir), _term_as_interrupt():
        return _run_locked(spec, out_dir, workers=workers, ray_address=ray_address,
                           retry_failed=retry_failed, on_start=on_start, on_row=on_row)


@contextlib.contextmanager
def _term_as_interrupt() -> Iterator[None]:
    """SIGTERM ends a sweep as Ctrl-C does: workers and Ray are shut down, what finished is
    on disk (the default action would end the process without any clean-up)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGTERM, _interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def _run_locked(spec: SweepSpec, out_dir: str | Path, *, workers: int | None,
                ray_address: str | None, retry_failed: bool,
                on_start: Callable[[SweepSummary, int], None] | None,
                on_row: Callable[[dict[str, Any]], None] | None) -> SweepSummary:
    t0 = time.perf_counter()
    tasks, summary, results = plan_sweep(spec, out_dir, retry_failed=retry_failed)
    write_spec_json(spec, summary.out_dir)
    if on_start is not None:
        on_start(summary, len(tasks))
    workers = max(1, workers or os.cpu_count() or 1)
    results.open_for_append()
    try:
        dispatch(tasks, ray_address, workers, row_sink(results, summary, on_row))
    finally:
        results.close()
        summary.wall_s = time.perf_counter() - t0
    return summary


# ------------------------------------------------------------------------------- process pool


def _worker_init(parent: int) -> None:
    """In each pool worker: leave Ctrl-C to the parent, and exit when the parent is gone
    (a SIGKILL-ed sweep must not leave workers behind)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os._exit(3)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _new_pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                               initializer=_worker_init, initargs=(os.getpid(),))


def _kill_pool(pool: ProcessPoolExecutor) -> None:
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        if proc.is_alive():
            proc.kill()
    for proc in procs:
        proc.join(timeout=5)


def run_pool(tasks: Iterable[Any], workers: int, sink: Callable[[Any], None], *,
             fn: Callable[[Any], Any] = run_task,
             fail: Callable[[Any, str], Any] = failed_row) -> None:
    """Keep ``2 x workers`` tasks in flight, ``sink(fn(task))`` as each ends. When a worker
    dies, the pool is rebuilt and the tasks it held run again one at a time; one that kills
    its worker alone, or raises outside ``fn``'s own handling, is ``sink(fail(task,
    error))``. ``fn`` and ``fail`` default to a sweep's episodes (``warerover study`` passes
    its own: module-level functions, pickled by name)."""
    pending = deque(tasks)
    suspects: deque[Task] = deque()
    inflight: dict[Future, tuple[Task, bool]] = {}
    pool = _new_pool(workers)
    try:
        while pending or suspects or inflight:
            broken = False
            while not broken:
                if suspects:
                    if inflight:
                        break
                    task, alone = suspects.popleft(), True
                elif pending and len(inflight) < 2 * workers:
                    task, alone = pending.popleft(), False
                else:
                    break
                try:
                    inflight[pool.submit(fn, task)] = (task, alone)
                except BrokenProcessPool:
                    (suspects if alone else pending).appendleft(task)
                    broken = True
                if alone:
                    break
            if not broken:
                done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
                for fut in done:
                    task, alone = inflight.pop(fut)
                    err = fut.exception()
                    if err is None:
                        sink(fut.result())
                    elif isinstance(err, BrokenProcessPool):
                        broken = True
                        _dead_worker(task, alone, suspects, sink, fail)
                    elif isinstance(err, KeyboardInterrupt):
                        raise KeyboardInterrupt
                    else:
                        sink(fail(task, f"{type(err).__name__}: {err}"))
            if broken:
                for fut, (task, alone) in list(inflight.items()):
                    if fut.done() and fut.exception() is None:
                        sink(fut.result())
                    else:
                        _dead_worker(task, alone, suspects, sink, fail)
                inflight.clear()
                _kill_pool(pool)
                log.warning("a worker process died; restarting the pool")
                pool = _new_pool(workers)
    finally:
        _kill_pool(pool)


def pool_map(fn: Callable[[Any], Any], items: Iterable[Any], workers: int,
             ) -> Iterator[tuple[Any, Any, BaseException | None]]:
    """Run ``fn(item)`` for every item in the sweep's process pool (``workers`` processes,
    spawned, leaving Ctrl-C to the parent and exiting with it) and yield ``(item, result,
    error)`` as each finishes; ``workers <= 1`` runs them here, one by one. A worker that
    dies fails its item (``BrokenProcessPool``) and the pool is rebuilt for the rest.
    ``fn`` must be a module-level function (it is pickled by name)."""
    todo = deque(items)
    if workers <= 1:
        for item in todo:
            try:
                yield item, fn(item), None
            except Exception as err:  # noqa: BLE001 - handed to the caller
                yield item, None, err
        return
    pool = _new_pool(workers)
    inflight: dict[Future, Any] = {}
    try:
        while todo or inflight:
            while todo and len(inflight) < 2 * workers:
                item = todo.popleft()
                try:
                    inflight[pool.submit(fn, item)] = item
                except BrokenProcessPool:
                    todo.appendleft(item)
                    break
            done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
            broken = False
            for fut in done:
                item = inflight.pop(fut)
                err = fut.exception()
                if isinstance(err, KeyboardInterrupt):
                    raise KeyboardInterrupt
                broken |= isinstance(err, BrokenProcessPool)
                yield item, (fut.result() if err is None else None), err
            if broken:
                for fut, item in list(inflight.items()):
                    err = fut.exception() if fut.done() else BrokenProcessPool("pool rebuilt")
                    yield item, (fut.result() if err is None else None), err
                inflight.clear()
                _kill_pool(pool)
                pool = _new_pool(workers)
    finally:
        _kill_pool(pool)


def _dead_worker(task: Any, alone: bool, suspects: deque[Any], sink: Callable[[Any], None],
                 fail: Callable[[Any, str], Any] = failed_row) -> None:
    if alone:
        sink(fail(task, "worker process died while running this episode (alone)"))
    else:
        suspects.append(task)


# ------------------------------------------------------------------------------- Ray


RAY_CONNECT_S = 3.0
"""Seconds a Ray cluster address gets to answer before a sweep starts."""
_GCS_PROBE = """
import sys
import ray._raylet as r
r.GcsClient(address=sys.argv[1]).internal_kv_get(b"warerover-probe", timeout=%r)
"""
"""Asks the cluster's GCS (Ray's head) one question, in a child process."""


def check_ray_address(address: str, timeout_s: float = RAY_CONNECT_S) -> None:
    """Refuse, before a sweep takes its folder, a ``--ray`` cluster address where no Ray
    cluster answers (``ray.init`` would retry until killed): a TCP connection within
    ``timeout_s``, then (a GCS address, not ``ray://``) one request to the cluster's GCS in
    a child process given a few seconds more (a proxy or another server that accepts the
    connection does not answer it). ``auto`` and ``local`` are left to Ray, which must be
    installed."""
    import socket
    import subprocess

    _import_ray()
    if address in ("auto", "local"):
        return
    hostport = address.split("://", 1)[-1]
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise WareroverError(f"--ray: expected HOST:PORT, auto or local (got {address!r})")
    why = None
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except OSError as err:
        why = "no answer" if isinstance(err, TimeoutError) else (err.strerror or str(err))
    if why is None and "://" not in address:
        try:
            probe = subprocess.run([sys.executable, "-c", _GCS_PROBE % timeout_s, hostport],
                                   capture_output=True, text=True, timeout=timeout_s + 5)
            if probe.returncode:
                lines = probe.stderr.strip().splitlines()
                why = f"not a Ray GCS: {lines[-1][:120] if lines else probe.returncode}"
        except subprocess.TimeoutExpired:
            why = "the GCS does not answer"
    if why is not None:
        raise WareroverError(f"--ray {address}: cannot reach a Ray cluster there ({why}); "
                             "start one with `ray start --head` or use --ray local")


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise WareroverError("--ray: Ray is not installed (pip install "
                             "'warerover-phys[ray]')") from None
    return ray


def run_ray(tasks: Iterable[Any], address: str, workers: int, sink: Callable[[Any], None], *,
            fn: Callable[[Any], Any] = run_task,
            fail: Callable[[Any, str], Any] = failed_row) -> None:
    """Run the tasks as Ray tasks (1 CPU each), ``2 x cluster CPUs`` in flight (``fn`` and
    ``fail`` as in :func:`run_pool`)."""
    ray = _import_ray()
    started = False
    reaper = None
    if not ray.is_initialized():
        from .reaper import start_reaper

        reaper = start_reaper()   # ends Ray's processes if this driver is SIGKILL-ed
        try:
            if address == "local":
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=address, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as err:
            from .reaper import stop_reaper

            stop_reaper(reaper)
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise WareroverError(f"--ray {address}: cannot connect to a Ray cluster ({first}); "
                                 "start one with `ray start --head` or use --ray local") from None
        started = True
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, _interrupt)    # ray.init installed its own
    remote = ray.remote(num_cpus=1, max_retries=1)(fn)
    capacity = max(2, 2 * int(ray.cluster_resources().get("CPU", workers)))
    pending = deque(tasks)
    inflight: dict[Any, Task] = {}
    try:
        while pending or inflight:
            while pending and len(inflight) < capacity:
                task = pending.popleft()
                inflight[remote.remote(task)] = task
            ready, _ = ray.wait(list(inflight), num_returns=1)
            for ref in ready:
                task = inflight.pop(ref)
                try:
                    row = ray.get(ref)
                except ray.exceptions.RayError as err:
                    first = str(err).strip().splitlines()[0] if str(err).strip() else ""
                    row = fail(task, f"ray: {type(err).__name__}: {first}")
                sink(row)
    finally:
        for ref in inflight:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()
        from .reaper import stop_reaper

        stop_reaper(reaper)
