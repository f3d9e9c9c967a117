"""Fits run side by side: each job fits some knob groups on a base model; a pool of processes,
started once per diagnosis with the data, runs the jobs and reports each as it finishes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from jetpipe_ros.diagnosis.calibration import group
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


_WORKER: dict = {}  #: the data a fitting process was started with


def _init_worker(prepared: Prepared, other: Prepared | None) -> None:
    threadpool_limits(1)  # small matrices: BLAS threads would only spin (see diagnose)
    _WORKER.update(prepared=prepared, other=other)


def _run(job: Job, prepared: Prepared | None = None, other: Prepared | None = None) -> Fit:
    data = (other if job.swapped else prepared) if prepared is not None else \
        _WORKER["other" if job.swapped else "prepared"]
    return fit(data, job.base, [group(g) for g in job.groups], job.start, job.budget)


class Fitter:
    """Runs fitting jobs in ``workers`` processes (1 = in this process), reporting progress.

    The data go to each process once, when the pool starts, not with every job; ``other`` is
    the same data with train and holdout exchanged (for cross-checks).
    """

    def __init__(self, prepared: Prepared, other: Prepared, workers: int,
                 progress: Callable[[str], None]) -> None:
        self.prepared = prepared
        self.other = other
        self.progress = progress
        self.pool = (ProcessPoolExecutor(max_workers=workers, initializer=_init_worker,
                                         initargs=(prepared, other)) if workers > 1 else None)

    def __enter__(self) -> Fitter:
        return self

    def __exit__(self, *exc) -> None:
        if self.pool is not None:
            self.pool.shutdown(cancel_futures=True)

    def run(self, jobs: Sequence[Job], labels: Sequence[str] | None = None) -> list[Fit]:
        """Run ``jobs``; return their fits in the order of the jobs. ``labels`` name the jobs
        in the progress lines (default: the fit's name)."""
        fits: list[Fit | None] = [None] * len(jobs)

        def report(i: int, done: int, f: Fit) -> None:
            fits[i] = f
            name = labels[i] if labels else f.name
            self.progress(f"  [{done}/{len(jobs)}] {name}: held-out gap {f.holdout.gap:.2f} % "
                          f"({f.evaluations} runs, {f.seconds:.1f} s)")

        if self.pool is None or len(jobs) == 1:
            for i, job in enumerate(jobs):
                report(i, i + 1, _run(job, self.prepared, self.other))
        else:
            futures = {self.pool.submit(_run, job): i for i, job in enumerate(jobs)}
            for done, fut in enumerate(as_completed(futures), 1):
                report(futures[fut], done, fut.result())
        return fits  # type: ignore[return-value]
