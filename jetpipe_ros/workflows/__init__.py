"""Running and judging the diagnosis: one dataset to its report (``jetpipe diagnose``), a fleet of
datasets, the self-check against withheld truths, the Dask cluster they run on, and the HTML
report a person reads."""

from jetpipe_ros.workflows.diagnose import diagnose

__all__ = ["diagnose"]
