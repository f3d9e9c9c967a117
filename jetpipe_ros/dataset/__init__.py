"""Datasets on disk (docs/data.md): experiment CSVs and the dataset.yaml index; friction-rig
records (docs/friction.md)."""

from jetpipe_ros.dataset.dataset import (Dataset, Entry, grouped_notes, read_dataset, read_index,
                                        write_dataset)
from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.dataset.friction_rig import RigRecord, read_records
from jetpipe_ros.dataset.experiment import (COMPLETE, MEASURED, REQUIRED, Experiment,
                                            measured_later, read_experiment, write_experiment)

__all__ = ["COMPLETE", "MEASURED", "REQUIRED", "Dataset", "DatasetError", "Entry", "Experiment",
           "RigRecord", "grouped_notes", "measured_later", "read_dataset", "read_experiment",
           "read_index", "read_records", "write_dataset", "write_experiment"]
