"""Fits run side by side: each job fits some knob groups on a base model; the jobs of one call
run on whatever :class:`Workers` the caller gives (a Dask cluster: :mod:`jetpipe_ros.workflows.
cluster`), each reported as it finishes, or one after the other in this process
(:data:`IN_PROCESS`). Both ways run :func:`run_job`. The diagnosis does not start or choose the
workers: whoever runs it does.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from jetpipe_ros.diagnosis.calibration import group
from jetpipe_ros.diagnosis.data import Prepared
from jetpipe_ros.diagnosis.fit import BUDGET, Fit, fit
from jetpipe_ros.model import ModelParams


class Workers(Protocol):
    """Where fitting jobs run. ``parallel``: on other processes (else :class:`Fitter` runs
    them here, one after the other)."""

    parallel: bool

    def share(self, data: Sequence[Any]) -> list:
        """Send ``data`` to every worker once; handles the jobs carry instead of the data."""

    def release(self, handles: list) -> None:
        """Free what :meth:`share` sent."""

    def completed(self, fn: Callable, items: Sequence[Any], *shared: Any
                  ) -> Iterator[tuple[int, Any]]:
        """``fn(item, *shared)`` of every item on the workers: (index, result) as each ends."""


class InProcess:
    """No workers: every job runs in this process."""

    parallel = False

    def __str__(self) -> str:
        return "this process"


#: The jobs run here, one after the other.
IN_PROCESS = InProcess()


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
    #: fit and judge on every record (:func:`jetpipe_ros.diagnosis.pooled.whole`)
    pooled: bool = False
    #: without ``start``: where the grid's other knobs sit (given, the grid leaves the first
    #: knob's neutral value out: :func:`fit.fit`)
    grid_base: np.ndarray | None = None


def run_job(job: Job, prepared: Prepared, other: Prepared, every: Prepared | None = None
            ) -> Fit:
    """One fit: on ``prepared``, on ``other`` (train and holdout exchanged) if swapped, or on
    ``every`` (every record both) if pooled."""
    if job.pooled and every is None:
        raise ValueError("a pooled job needs the data with every record both training and "
                         "held-out")
    data = every if job.pooled else other if job.swapped else prepared
    return fit(data, job.base, [group(g, data.sensors) for g in job.groups],
               job.start, job.budget, job.grid_base)


class Fitter:
    """Runs fitting jobs on ``workers`` (or in this process when they are not parallel),
    reporting progress.

    The data go to every worker once, at the first call that uses them (:meth:`Workers.share`;
    the jobs carry the handles), not with every job; ``other`` is the same data with train and
    holdout exchanged (for cross-checks), ``every`` with every record both (for pooled jobs).
    A call with a single job runs it in this process.
    """

    def __init__(self, prepared: Prepared, other: Prepared, workers: Workers,
                 progress: Callable[[str], None], every: Prepared | None = None) -> None:
        self.prepared = prepared
        self.other = other
        self.every = every
        self.workers = workers
        self.progress = progress
        #: handles of (prepared, other[, every]) on the workers, ``every`` from the first call
        #: that needs it
        self._data: list | None = None

    def __enter__(self) -> Fitter:
        return self

    def __exit__(self, *exc) -> None:
        if self._data is not None:
            self.workers.release(self._data)  # frees the workers' copies
            self._data = None

    def _shared(self, every: bool) -> list:
        """The handles of the data on every worker (each sent once): ``prepared`` and
        ``other``, and with ``every`` (a call that holds a pooled job) that data too, sent only
        then: most diagnoses name an effect and never run one."""
        if self._data is None:
            self._data = self.workers.share([self.prepared, self.other])
            self.progress(f"  fitting on {self.workers} (data sent to every worker)")
        if every and len(self._data) == 2 and self.every is not None:
            self._data = self._data + self.workers.share([self.every])
        return self._data if every else self._data[:2]

    def run(self, jobs: Sequence[Job], labels: Sequence[str] | None = None) -> list[Fit]:
        """Run ``jobs``; return their fits in the order of the jobs. ``labels`` name the jobs
        in the progress lines (default: the fit's name)."""
        fits: list[Fit | None] = [None] * len(jobs)

        def report(i: int, done: int, f: Fit) -> None:
            fits[i] = f
            name = labels[i] if labels else f.name
            self.progress(f"  [{done}/{len(jobs)}] {name}: held-out gap {f.holdout.gap:.2f} % "
                          f"({f.evaluations} runs, {f.seconds:.1f} s)")

        if len(jobs) == 1 or not self.workers.parallel:
            for i, job in enumerate(jobs):
                report(i, i + 1, run_job(job, self.prepared, self.other, self.every))
        else:
            shared = self._shared(any(job.pooled for job in jobs))
            for done, (i, f) in enumerate(self.workers.completed(run_job, jobs, *shared), 1):
                report(i, done, f)
        return fits  # type: ignore[return-value]
