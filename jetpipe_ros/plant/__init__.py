"""A stand-in for real hardware, written apart from the model's effects.

The plant simulates the actuator with the pinned nominal physics of docs/model.md (the model's
one copy of each pinned equation: Eq. 8, Eq. 13, the friction planes and Eq. 15/18, the valve
chain's exact discretisation, the parameters) and, switched on at will, real effects in other
functional forms than the model's candidates, and effects on no list, each with its own
equations (in the docstrings of ``valve``, ``chambers``, ``mechanics`` and ``sensors``). Its
own compiled loop (``loop``) integrates in 8 sub-steps per sample. :class:`Plant` has the
interface of the model's ``Actuator``, so the offline campaign runner records datasets on it
(:func:`campaign_dataset`); :data:`REAL_EFFECTS` says what each effect is to the diagnosis and
draws it at a realistic size.
"""

from jetpipe_ros.plant.campaign import campaign_dataset
from jetpipe_ros.plant.effects import REAL_EFFECTS, RealEffect
from jetpipe_ros.plant.errors import PlantError
from jetpipe_ros.plant.plant import Plant, simulate
from jetpipe_ros.plant.spec import EFFECT_PARAMS, PlantSpec

__all__ = ["EFFECT_PARAMS", "REAL_EFFECTS", "Plant", "PlantError", "PlantSpec", "RealEffect",
           "campaign_dataset", "simulate"]
