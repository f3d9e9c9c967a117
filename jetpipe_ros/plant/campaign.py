"""Datasets recorded on the plant: the default campaign run through it offline."""

from __future__ import annotations

from pathlib import Path

from jetpipe_ros.campaign import campaign_dataset as on_model
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant.plant import Plant
from jetpipe_ros.plant.spec import PlantSpec


def campaign_dataset(spec: PlantSpec, root: str | Path, seed: int,
                     sample_time: float | None = None) -> Path:
    """Write the default campaign (``config/campaign.yaml``) recorded on the plant ``spec`` to
    the dataset directory ``root``, as :func:`jetpipe_ros.campaign.campaign_dataset` does on the
    model: sensor noise as ``spec.params`` says, seeded with ``seed % 100000``, at the plan's
    sample time or ``sample_time`` [s]."""

    def plant(params: ModelParams) -> Plant:
        return Plant(spec.with_params(params))

    return on_model(spec.params, root, seed, sample_time, actuator=plant)
