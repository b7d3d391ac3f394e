"""Independent tasks on an engine: this process, local worker processes, or a Dask cluster.

Used by ``glpma-fk map`` (chunks of the grid) and ``glpma-fk bag`` with several inputs (one bag
per task).  :func:`run_tasks` calls ``fn(*shared, *task)`` for every task and hands each result to
``done`` in this process as it finishes (in completion order); the results themselves do not
depend on the engine, only the order in which ``done`` sees them.

* ``workers == 1`` (or a single task): in this process, in order;
* ``workers > 1``: a ``ProcessPoolExecutor`` of spawned processes (a clean interpreter per worker,
  no forked threads; Numba loads its cache there);
* ``scheduler``: a Dask distributed cluster (``Client(scheduler)``); ``shared`` is scattered to
  every worker once, and the workers need the package installed.
"""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed

from glpma_ros.errors import GlpmaError, InputError

#: how long to try to reach a Dask scheduler
DASK_CONNECT_TIMEOUT = "5s"


class EngineError(GlpmaError):
    """A worker failed (exit status 1: not the user's input)."""

    #: the command's exit status (:func:`glpma_ros.cli.api.command_main`)
    exit_status = 1


def engine_name(workers: int, scheduler: str | None) -> str:
    return f"Dask {scheduler}" if scheduler else "this process" if workers == 1 else f"{workers} processes"


def run_serial(fn, shared: tuple, tasks, done) -> None:
    for task in tasks:
        done(fn(*shared, *task))


def run_processes(fn, shared: tuple, tasks, done, workers: int) -> None:
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(fn, *shared, *task) for task in tasks]
        try:
            for future in as_completed(futures):
                done(future.result())
        except BaseException:
            for future in futures:
                future.cancel()
            raise


def run_dask(fn, shared: tuple, tasks, done, scheduler: str) -> None:
    from dask.distributed import Client, as_completed  # the map extra: optional, imported where used
    try:
        client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"cannot reach the Dask scheduler {scheduler}: {str(exc).splitlines()[0]}") from None
    with client:
        scattered = client.scatter(list(shared), broadcast=True) if shared else []
        futures = [client.submit(fn, *scattered, *task, pure=False) for task in tasks]
        try:
            for future in as_completed(futures):
                done(future.result())
        except BaseException:
            client.cancel(futures)
            raise


def run_tasks(fn, tasks, done, *, shared: tuple = (), workers: int = 1, scheduler: str | None = None) -> None:
    """``done(fn(*shared, *task))`` for every task, on the engine ``workers`` / ``scheduler`` name.
    A worker's failure is an :class:`EngineError` whose message starts with the engine's name (a
    :class:`GlpmaError` of the task itself, e.g. bad input, passes through)."""
    tasks = list(tasks)
    try:
        if not tasks:
            return
        if scheduler:
            run_dask(fn, shared, tasks, done, scheduler)
        elif workers == 1 or len(tasks) == 1:
            run_serial(fn, shared, tasks, done)
        else:
            run_processes(fn, shared, tasks, done, min(workers, len(tasks)))
    except (GlpmaError, KeyboardInterrupt):
        raise
    except Exception as exc:  # noqa: BLE001 - a worker's failure, reported in one line
        raise EngineError(f"{engine_name(workers, scheduler)}: {type(exc).__name__}: {exc}") from None
