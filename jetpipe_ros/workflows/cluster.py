"""Where the work of a diagnosis, a fleet or a self-check runs: Dask distributed workers, or this
process (the diagnosis's :class:`~jetpipe_ros.diagnosis.jobs.Workers`).

A :class:`Cluster` gives a :class:`distributed.Client` of

- the Dask scheduler at ``--scheduler`` (``tcp://host:8786``), else at the address in the
  ``DASK_SCHEDULER_ADDRESS`` environment variable (Dask's own ``scheduler-address`` setting):
  ``dask scheduler`` and ``dask worker`` processes on machines that have this package installed
  and see the datasets and the output directory under the same paths as this one;
- else a :class:`distributed.LocalCluster` started here: ``workers`` processes (at most one per
  core) of one thread each, since the numba kernels hold the GIL; no dashboard;
- else none, for ``workers == 1``: the work runs in this process, through the same functions.

A cluster starts in a background thread as soon as it is entered, so that its start (measured in
``bench/bench_fleet.py``: README, Benchmarks) overlaps the caller's own work until the client is
first needed. Every worker is warmed once as it joins (:class:`Warm`): BLAS limited to one thread
(the matrices here are small: more threads only spin and take the cores the other workers need),
the package imported and the compiled kernels loaded from numba's on-disk cache (``cache=True``)
by a tiny simulation, so no task pays for them (the plant's too, for a self-check, which
records on it: ``plant=True``).
"""

from __future__ import annotations

import logging
import os
import threading
import time

import dask
import numpy as np
from distributed import Client, LocalCluster, WorkerPlugin, as_completed
from threadpoolctl import threadpool_limits

from jetpipe_ros.model import ParameterError

#: How long to try reaching a scheduler before giving up [s].
CONNECT_TIMEOUT_S = 10
#: Settings of local workers. No statistical profiler: it samples the task thread's stack every
#: 10 ms, and a fit's evaluations, many short calls into numba kernels, ran about 15 % slower
#: with it (measured: ``predict_all`` 35 ms in this process, 41-50 ms in a worker with it,
#: 38-41 ms without). Workers started by hand take it from
#: ``DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False``. And the environment Dask gives its
#: worker processes without ``MALLOC_TRIM_THRESHOLD_``: setting it at all turns off glibc's
#: dynamic mmap threshold, so every array of a simulation's size is mapped and unmapped afresh
#: (measured: ``predict_all`` 36-40 ms in a plain process, 51 ms with the variable at Dask's
#: 65536). The one-thread settings for the numerical libraries stay.
WORKER_CONFIG = {"distributed.worker.profile.enabled": False,
                 "distributed.nanny.pre-spawn-environ": {
                     "OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1}}


def close_local(cluster: LocalCluster) -> None:
    """Close a local cluster that was started here. Its worker processes are asked to stop, then
    killed, and each is given Dask's fixed 5 s to be reaped after the kill; on a loaded host
    (seen: a test suite beside a self-check on two cores) the reaping can take longer and Dask
    raises ``TimeoutError`` although the process is gone. That is not the caller's failure:
    everything it computed is already in hand."""
    try:
        cluster.close()
    except TimeoutError:
        logging.getLogger(__name__).info("a worker process was killed but not yet reaped "
                                         "within 5 s while closing the local cluster")


class ClusterError(ParameterError):
    """The Dask scheduler cannot be reached or the cluster cannot start; the message names the
    option or environment variable that chose it."""


class Warm(WorkerPlugin):
    """Set up each worker once as it joins the cluster: one BLAS thread, the package imported,
    the model's compiled kernels loaded (a 20-sample simulation), and the plant's with
    ``plant``."""

    def __init__(self, plant: bool = False) -> None:
        self.plant = plant

    def setup(self, worker=None) -> None:
        threadpool_limits(1)
        from jetpipe_ros.model import ModelParams, simulate

        simulate(ModelParams(), np.zeros(20))
        if self.plant:
            from jetpipe_ros.plant import PlantSpec
            from jetpipe_ros.plant import simulate as simulate_plant

            simulate_plant(PlantSpec(), np.zeros(20))


class Cluster:
    """The Dask client the work is submitted to (see the module docstring), as a context
    manager: entering starts the cluster in the background, leaving closes what was started
    here (a scheduler given by address is only disconnected from).

    ``workers``: worker processes of a local cluster (capped at the number of cores; 1: no
    cluster, the work runs in this process); ignored when a scheduler address is given.
    ``plant``: warm the plant's kernels on every worker as well (:class:`Warm`).
    """

    def __init__(self, workers: int = 2, scheduler: str | None = None,
                 plant: bool = False) -> None:
        if workers < 1:
            raise ParameterError(f"--jobs {workers}: must be at least 1")
        env = dask.config.get("scheduler-address", None)
        self.address: str | None = scheduler or env or None
        self.source = "--scheduler" if scheduler else "DASK_SCHEDULER_ADDRESS"
        self.workers = workers if self.address else min(workers, os.cpu_count() or 1)
        self.startup_s: float | None = None  #: seconds from entering to warmed workers
        self._client: Client | None = None
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        self._plant = plant

    def __str__(self) -> str:
        if self.address:
            return f"the Dask scheduler at {self.address}"
        return (f"{self.workers} local Dask worker processes" if self.workers > 1
                else "this process")

    @property
    def parallel(self) -> bool:
        """Work goes to Dask workers (else it runs in this process)."""
        return bool(self.address) or self.workers > 1

    def __enter__(self) -> Cluster:
        if self.parallel:
            self._thread = threading.Thread(target=self._start, name="jetpipe-cluster",
                                            daemon=True)
            self._thread.start()
        return self

    def _start(self) -> None:
        t0 = time.perf_counter()
        try:
            if self.address:
                client = Client(self.address, timeout=CONNECT_TIMEOUT_S)
            else:
                with dask.config.set(WORKER_CONFIG):  # passed on to the worker processes
                    client = Client(LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                                 processes=True, dashboard_address=None,
                                                 silence_logs=logging.ERROR))
            client.register_plugin(Warm(self._plant), name="jetpipe-warm")
            self._client = client
        except Exception as exc:  # raised where the client is first needed  # noqa: BLE001
            self._error = exc
        self.startup_s = time.perf_counter() - t0

    @property
    def client(self) -> Client | None:
        """The client once the cluster is up and warm (waits for it); None: run here."""
        if self._thread is None:
            return None
        self._thread.join()
        if self._error is not None:
            where = (f"{self.source} {self.address}" if self.address
                     else f"a local cluster of {self.workers} workers")
            raise ClusterError(f"{where}: cannot start or connect: {self._error}")
        return self._client

    def __exit__(self, *exc) -> None:
        if self._thread is None:
            return
        self._thread.join()
        client, self._client, self._thread = self._client, None, None
        if client is not None:
            local = client.cluster if not self.address else None
            client.close()
            if local is not None:
                close_local(local)

    def share(self, data: list) -> list:
        """Send ``data`` to every worker once (scattered with ``broadcast=True``); the futures
        jobs carry instead of the data."""
        return self.client.scatter(data, broadcast=True, hash=False)

    def release(self, handles: list) -> None:
        """Free what :meth:`share` sent."""
        self.client.cancel(handles)

    def completed(self, fn, items, *shared):
        """``fn(item, *shared)`` of every item on the workers: (index, result) as each ends;
        what is still running is cancelled if the caller stops early or a task fails."""
        futures = [self.client.submit(fn, item, *shared, pure=False) for item in items]
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for fut in as_completed(futures):
                yield index[fut.key], fut.result()
        finally:
            self.client.cancel(futures)
