"""Errors raised while reading or writing datasets."""


class DatasetError(ValueError):
    """A dataset file is missing, malformed or inconsistent; the message names file and place."""
