"""Sim-to-real gap diagnosis: where the model departs from measurements, which unmodelled effect
causes it, and how far the gap shrinks once that effect is modelled. :func:`diagnose_dataset`
diagnoses a dataset in memory; :func:`jetpipe_ros.workflows.diagnose` (``jetpipe diagnose``)
reads a dataset directory and writes the outputs and the report."""

from jetpipe_ros.diagnosis.diagnose import Diagnosis, diagnose_dataset

__all__ = ["Diagnosis", "diagnose_dataset"]
