"""Datasets recorded on the plant: the default campaign run through it offline."""

from __future__ import annotations

from pathlib import Path

from jetpipe_ros.campaign import default_campaign, run_campaign_offline
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant.plant import Plant
from jetpipe_ros.plant.spec import PlantSpec


def campaign_dataset(spec: PlantSpec, root: str | Path, seed: int) -> Path:
    """Write the default campaign (``config/campaign.yaml``) recorded on the plant ``spec`` to
    the dataset directory ``root``, as ``jetpipe_ros.diagnosis.cli.campaign_dataset`` does on
    the model: sensor noise as ``spec.params`` says, seeded with ``seed % 100000``."""

    def plant(params: ModelParams) -> Plant:
        return Plant(spec.with_params(params))

    return run_campaign_offline(spec.params, default_campaign(), root, seed=seed % 100000,
                                actuator=plant)
