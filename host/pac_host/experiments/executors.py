"""Where independent tasks run: in this process, a local process pool, or a Dask cluster.

Every task the experiment and the sweep hand out is a pure function of its arguments (each
carries its own seed), so the engine changes the wall time, never the results. A Dask cluster
(``distributed``) is the engine beyond one machine: a worker that dies has its tasks rerun by
the scheduler, and the results are gathered back here.

>>> with local_executor(1) as ex:
...     ex.map(pow, [(2, 3), (3, 2)])
[8, 9]
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError, ProcessPoolExecutor

from pac_host.errors import InputError, PacError

Done = Callable[[object], None] | None

# Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers; that turns glibc's adaptive mmap
# threshold off, so numpy's temporaries are mapped and unmapped on every call: the coverage
# simulator then takes 25-35% more CPU time on a worker than in this process (measured). Our
# workers keep glibc's default (a remote cluster's: see docs/how-to/sweep.md).
WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


class Executor:
    """Maps a function over argument tuples; ``done`` sees each result as it arrives.

    ``shares_files``: tasks may write files in this process's file system (a pool on this
    machine); otherwise a task returns everything it made and this side writes it.
    ``slots``: how many tasks run at once.
    """

    shares_files = True
    slots = 1

    def map(self, fn: Callable, args: Sequence[tuple], done: Done = None) -> list:
        out = []
        for a in args:
            out.append(fn(*a))
            if done:
                done(out[-1])
        return out

    def close(self) -> None:
        pass

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class InProcess(Executor):
    """One task after the other, in this process."""


class ProcessPool(Executor):
    """A pool of worker processes on this machine (results in submission order)."""

    def __init__(self, jobs: int):
        self.slots = jobs
        self._pool: ProcessPoolExecutor | None = None

    def map(self, fn: Callable, args: Sequence[tuple], done: Done = None) -> list:
        if len(args) <= 1:  # not worth starting processes for
            return super().map(fn, args, done)
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.slots)
        futs = [self._pool.submit(fn, *a) for a in args]
        out = []
        for fut in futs:
            out.append(fut.result())
            if done:
                done(out[-1])
        return out

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None


def local_executor(jobs: int) -> Executor:
    """``jobs`` worker processes on this machine; 1 runs in this process."""
    return InProcess() if jobs <= 1 else ProcessPool(jobs)


class DaskExecutor(Executor):
    """Tasks on a Dask cluster through a ``distributed.Client`` (thread-safe: several
    experiments may map through one executor at once)."""

    shares_files = False  # a worker may be another machine

    def __init__(self, client, cluster=None):
        self.client = client
        self._cluster = cluster  # a LocalCluster this executor started and so closes

    @property
    def slots(self) -> int:
        return max(1, sum(self.client.nthreads().values()))

    def map(self, fn: Callable, args: Sequence[tuple], done: Done = None) -> list:
        from distributed import KilledWorker, as_completed

        futs = [self.client.submit(fn, *a, pure=False) for a in args]
        try:
            for fut in as_completed(futs):
                res = fut.result()
                if done:
                    done(res)
            return [f.result() for f in futs]
        except KilledWorker as e:
            raise PacError(f"the cluster gave a task up after it killed workers ({e}); finished "
                           "work is on disk: rerun with --resume") from None
        except CancelledError as e:  # the scheduler went away, or this client was closed
            why = str(e).splitlines()[0] if str(e) else "tasks cancelled"
            raise PacError(f"lost the Dask cluster ({why}); finished work is on disk: rerun "
                           "with --resume") from None
        finally:
            self.client.cancel([f for f in futs if not f.done()])

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


def dask_executor(scheduler: str | None = None, jobs: int = 1,
                  timeout: float = 10.0) -> DaskExecutor:
    """A client of the running scheduler at ``scheduler`` (``tcp://HOST:8786``), or of a new
    ``LocalCluster`` of ``jobs`` single-threaded worker processes."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler is None:
        cluster = None
        try:  # a worker that cannot start (no memory, no ports, a broken environment)
            with dask.config.set(WORKER_CONFIG):
                cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.ERROR)
            return DaskExecutor(Client(cluster), cluster)
        except (RuntimeError, OSError, TimeoutError) as e:
            if cluster is not None:
                cluster.close()
            why = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise PacError(f"the local Dask cluster of {jobs} workers could not start ({why}); "
                           "--jobs 1 runs the work in this process, without Dask") from None
    for name in ["distributed", *logging.root.manager.loggerDict]:  # errors reach the user
        if name.startswith("distributed"):                         # as ours, in one line
            logging.getLogger(name).setLevel(logging.CRITICAL)
    try:
        client = Client(scheduler, timeout=timeout)
    except (OSError, ValueError, TypeError) as e:
        raise InputError(f"cannot reach the Dask scheduler at {scheduler}: "
                         f"{str(e).splitlines()[0] if str(e) else type(e).__name__}") from None
    return DaskExecutor(client)  # workers may join later (a batch queue): tasks wait for them


def make_executor(jobs: int = 1, scheduler: str | None = None, timeout: float = 10.0,
                  local: Callable[[int], Executor] = local_executor) -> Executor:
    """The engine a command asked for: a Dask scheduler if given, else ``local(jobs)``."""
    return dask_executor(scheduler, timeout=timeout) if scheduler else local(jobs)
