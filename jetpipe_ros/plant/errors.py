"""Errors of the plant stand-in."""


class PlantError(ValueError):
    """A plant specification that cannot be simulated: unknown effect or parameter, a value out
    of range, or a model effect left on (the plant's effects are its own)."""
