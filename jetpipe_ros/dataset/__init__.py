"""Datasets on disk (DESIGN.md section 5): experiment CSVs and the dataset.yaml index."""

from jetpipe_ros.dataset.errors import DatasetError
from jetpipe_ros.dataset.experiment import Experiment, read_experiment, write_experiment

__all__ = ["DatasetError", "Experiment", "read_experiment", "write_experiment"]
