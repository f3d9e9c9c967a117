"""Identification campaigns, pure Python (no ROS): excitation signals, the plan read from
``config/campaign.yaml``, its schedule, and an offline runner that simulates a plan through the
model and writes the dataset the ``id_recorder`` node would record."""

from jetpipe_ros.campaign.errors import CampaignError
from jetpipe_ros.campaign.offline import campaign_dataset, run_campaign_offline
from jetpipe_ros.campaign.plan import (Campaign, Command, ExperimentSpec, Phase, SignalSpec,
                                       default_campaign, load_campaign, parse_campaign)

__all__ = ["Campaign", "CampaignError", "Command", "ExperimentSpec", "Phase", "SignalSpec",
           "campaign_dataset", "default_campaign", "load_campaign", "parse_campaign",
           "run_campaign_offline"]
