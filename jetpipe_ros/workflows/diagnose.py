"""``jetpipe diagnose DATASET_DIR --out OUT``: one dataset directory diagnosed on a Dask cluster
(or in this process), its outputs written whole: ``diagnosis.json``, ``report.html`` and
``augmented.yaml`` go to a temporary directory and are moved into place only when all three are
complete (docs/diagnosis.md)."""

from __future__ import annotations

from pathlib import Path

from jetpipe_ros import fileio
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.diagnosis.diagnose import Diagnosis, diagnose_dataset
from jetpipe_ros.model import ModelParams, ParameterError
from jetpipe_ros.model.limits import Limits
from jetpipe_ros.progress import Progress
from jetpipe_ros.workflows.cluster import Cluster
from jetpipe_ros.workflows.report import render

OUTPUTS = ("diagnosis.json", "report.html", "augmented.yaml")


def diagnose(dataset_dir: str | Path, out_dir: str | Path, params: ModelParams | None = None,
             workers: int = 2, quiet: bool = False, scheduler: str | None = None) -> dict:
    """Run the diagnosis on a dataset directory and write its outputs; return diagnosis.json's
    content.

    The candidate fits run on ``workers`` local Dask worker processes (1: in this process), or
    on the Dask cluster at ``scheduler`` / ``DASK_SCHEDULER_ADDRESS`` (:class:`Cluster`). The
    dataset is read, and ``out_dir`` checked, before the cluster starts: bad input fails at
    once; the cluster then starts while the records are prepared."""
    progress = Progress(quiet)
    nominal = params if params is not None else ModelParams()
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ParameterError(f"--out {out_dir}: exists and is not a directory")
    progress(f"reading {dataset_dir}")
    dataset = read_dataset(dataset_dir, limits=Limits.from_params(nominal))
    with Cluster(workers, scheduler) as cluster:
        found = diagnose_dataset(dataset, nominal, cluster, progress)
    progress(f"writing {out_dir}")
    write_outputs(out_dir, found)
    return found.result


def write_outputs(out_dir: Path, found: Diagnosis) -> None:
    """``diagnosis.json``, ``augmented.yaml`` and ``report.html`` of ``found`` into
    ``out_dir``: all three, or none."""
    header = ("# jetpipe diagnose: the nominal model plus the effect the diagnosis "
              f"identified ({found.result['verdict']['effect']}).\n")
    texts = {"diagnosis.json": fileio.to_json(found.result) + "\n",  # strict: NaN/inf as null
             "augmented.yaml": header + found.augmented.to_ros_yaml(only_changed=True),
             "report.html": render(found.result, found.prepared, found.predictions,
                                   found.remainders)}
    fileio.write_files({out_dir / name: texts[name] for name in OUTPUTS})
