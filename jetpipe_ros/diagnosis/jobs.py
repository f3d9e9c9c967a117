"""Fits run side by side: each job fits some knob groups on a base model; the jobs of one call
run on the workers of a Dask cluster (:mod:`cluster`), each reported as it finishes, or one
after the other in this process when there is no cluster. Both ways run :func:`run_job`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from distributed import as_completed

from jetpipe_ros.diagnosis.calibration import group
from jetpipe_ros.diagnosis.cluster import Cluster
from jetpipe_ros.diagnosis.data import Prepared
from jetpipe_ros.diagnosis.fit import BUDGET, Fit, fit
from jetpipe_ros.model import ModelParams


@dataclass(frozen=True)
class Job:
    """Fit ``groups`` (names, applied in order) on ``base``; ``start`` = unit-scaled knobs to
    start from, or several (rows) to start from the best of (None: a grid over the first knob
    of the first effect, see :func:`fit.fit`)."""

    base: ModelParams
    groups: tuple[str, ...]
    start: np.ndarray | None = None
    budget: int = BUDGET
    swapped: bool = False  #: fit on the holdout, judge on the training data (cross-check)
    grid_base: np.ndarray | None = None  #: without ``start``: where the grid's other knobs sit


def run_job(job: Job, prepared: Prepared, other: Prepared) -> Fit:
    """One fit: on ``prepared``, or on ``other`` (train and holdout exchanged) if swapped."""
    return fit(other if job.swapped else prepared, job.base, [group(g) for g in job.groups],
               job.start, job.budget, job.grid_base)


class Fitter:
    """Runs fitting jobs on ``cluster`` (or in this process without one), reporting progress.

    The data go to every worker once, at the first call that uses the cluster (scattered with
    ``broadcast=True``; the jobs carry references to them), not with every job; ``other`` is the
    same data with train and holdout exchanged (for cross-checks). A call with a single job runs
    it in this process.
    """

    def __init__(self, prepared: Prepared, other: Prepared, cluster: Cluster,
                 progress: Callable[[str], None]) -> None:
        self.prepared = prepared
        self.other = other
        self.cluster = cluster
        self.progress = progress
        self._data: list | None = None  #: futures of (prepared, other) on the workers

    def __enter__(self) -> Fitter:
        return self

    def __exit__(self, *exc) -> None:
        if self._data is not None:
            self.cluster.client.cancel(self._data)  # frees the workers' copies
            self._data = None

    def _shared(self):
        """The client and the futures of the data on every worker (scattered once)."""
        client = self.cluster.client
        if self._data is None:
            self._data = client.scatter([self.prepared, self.other], broadcast=True,
                                        hash=False)
            self.progress(f"  fitting on {self.cluster} (ready {self.cluster.startup_s:.1f} s "
                          f"after start, data sent to every worker)")
        return client, self._data

    def run(self, jobs: Sequence[Job], labels: Sequence[str] | None = None) -> list[Fit]:
        """Run ``jobs``; return their fits in the order of the jobs. ``labels`` name the jobs
        in the progress lines (default: the fit's name)."""
        fits: list[Fit | None] = [None] * len(jobs)

        def report(i: int, done: int, f: Fit) -> None:
            fits[i] = f
            name = labels[i] if labels else f.name
            self.progress(f"  [{done}/{len(jobs)}] {name}: held-out gap {f.holdout.gap:.2f} % "
                          f"({f.evaluations} runs, {f.seconds:.1f} s)")

        if len(jobs) == 1 or not self.cluster.parallel:
            for i, job in enumerate(jobs):
                report(i, i + 1, run_job(job, self.prepared, self.other))
        else:
            client, data = self._shared()
            futures = [client.submit(run_job, job, *data, pure=False) for job in jobs]
            index = {f.key: i for i, f in enumerate(futures)}
            try:
                for done, fut in enumerate(as_completed(futures), 1):
                    report(index[fut.key], done, fut.result())
            finally:
                client.cancel(futures)
        return fits  # type: ignore[return-value]
