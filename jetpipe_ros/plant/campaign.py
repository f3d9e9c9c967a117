"""Datasets recorded on the plant: the default campaign run through it offline."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from jetpipe_ros.campaign import default_campaign, run_campaign_offline
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant.plant import Plant
from jetpipe_ros.plant.spec import PlantSpec


def campaign_dataset(spec: PlantSpec, root: str | Path, seed: int,
                     sample_time: float | None = None) -> Path:
    """Write the default campaign (``config/campaign.yaml``) recorded on the plant ``spec`` to
    the dataset directory ``root``, as ``jetpipe_ros.diagnosis.cli.campaign_dataset`` does on
    the model: sensor noise as ``spec.params`` says, seeded with ``seed % 100000``, at the
    plan's sample time or ``sample_time`` [s]."""

    def plant(params: ModelParams) -> Plant:
        return Plant(spec.with_params(params))

    plan = default_campaign()
    if sample_time is not None:
        plan = dataclasses.replace(plan, sample_time=sample_time)
    return run_campaign_offline(spec.params, plan, root, seed=seed % 100000, actuator=plant)
