"""Sim-to-real gap diagnosis: where the model departs from measurements, which unmodelled effect
causes it, and how far the gap shrinks once that effect is modelled (``jetpipe diagnose``)."""

from jetpipe_ros.diagnosis.diagnose import diagnose

__all__ = ["diagnose"]
