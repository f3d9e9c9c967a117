"""Errors raised by the model package."""


class ParameterError(ValueError):
    """A parameter is unknown, of the wrong type or out of its range; the message names it."""
