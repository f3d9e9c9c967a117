"""Errors of campaign plans."""


class CampaignError(ValueError):
    """A campaign plan is malformed; the message names the file, the experiment and the field."""
