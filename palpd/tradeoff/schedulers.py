"""Independent tasks on Dask distributed (a LocalCluster, or an existing cluster by address), or on a
process pool where distributed is not installed. Results come back in task order whatever finished first,
and a task that fails is reported as that task's failure: the others go on."""
from __future__ import annotations

import logging
import os
from typing import Callable, Sequence

from palpd.errors import UsageError

CONNECT_TIMEOUT_S = 10
CLUSTER_EXTRA = "pip install 'palpd[cluster]'"
HEALTH_ONLY = "distributed.http.health"  # the one HTTP route a local cluster serves: /health, no pages


def has_distributed() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def execute(fn: Callable, tasks: Sequence, scheduler: str = "local", workers: int | None = None,
            done: Callable[[int, object, str | None], None] | None = None) -> list[tuple[object, str | None]]:
    """[(result, None) or (None, error)] per task, in task order; done(index, result, error) as each ends."""
    workers = workers or os.cpu_count() or 1
    if scheduler != "local" and "://" not in scheduler:
        raise UsageError(f"--scheduler {scheduler!r}: use local or a scheduler address such as tcp://HOST:8786")
    if has_distributed():
        return _on_dask(fn, tasks, scheduler, workers, done or _ignore)
    if scheduler != "local":
        raise UsageError(f"--scheduler {scheduler}: a Dask cluster needs the distributed package ({CLUSTER_EXTRA})")
    return _on_pool(fn, tasks, workers, done or _ignore)


def _ignore(*_args) -> None:
    """No one is watching the progress."""


def _on_dask(fn, tasks, scheduler: str, workers: int, done) -> list:
    from distributed import as_completed

    client, cluster = _connect(scheduler, workers)
    try:
        futures = client.map(fn, tasks, pure=False)
        order = {future.key: index for index, future in enumerate(futures)}
        return _collect(as_completed(futures), len(tasks), lambda future: order[future.key], done)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _connect(scheduler: str, workers: int):
    from distributed import Client

    if scheduler == "local":
        cluster = local_cluster(workers)
        return Client(cluster), cluster
    try:
        return Client(scheduler, timeout=CONNECT_TIMEOUT_S), None
    except (OSError, TimeoutError, ValueError) as exc:
        raise UsageError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({exc})") from None


def local_cluster(workers: int, processes: bool = True):
    """A LocalCluster on loopback with no dashboard. dashboard_address=None alone is not that: the scheduler
    still serves its HTTP routes (status pages, prometheus) on 0.0.0.0:8787, the workers on random ports.
    Here every node binds 127.0.0.1 and serves /health only; a dashboard is for a cluster started on purpose
    (--scheduler tcp://HOST:PORT)."""
    import dask
    from distributed import LocalCluster

    with dask.config.set({f"distributed.{node}.http.routes": [HEALTH_ONLY] for node in ("scheduler", "worker")}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes, protocol="tcp",
                            host="127.0.0.1", dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": False},
                            silence_logs=logging.ERROR)


def _on_pool(fn, tasks, workers: int, done) -> list:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # spawn: never fork a process whose libraries may hold threads
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(fn, task) for task in tasks]
        order = {future: index for index, future in enumerate(futures)}
        return _collect(as_completed(futures), len(tasks), order.__getitem__, done)


def _collect(finished, count: int, index_of, done) -> list:
    results: list = [None] * count
    for future in finished:
        index = index_of(future)
        try:
            results[index] = (future.result(), None)
        except Exception as exc:  # one task's failure, whatever it was, is that task's
            results[index] = (None, describe(exc))
        done(index, *results[index])
    return results


def describe(exc: BaseException) -> str:
    """One line for a failed task: palpd's own errors say what is wrong; anything else names its type."""
    from palpd.errors import PalpdError

    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return text if isinstance(exc, PalpdError) else f"{type(exc).__name__}: {text}".rstrip(": ")
