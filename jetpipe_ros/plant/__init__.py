"""A stand-in for real hardware, written apart from the model: its physics and its effects.

The plant simulates the actuator with the paper's nominal physics evaluated by its own code
(Eq. 8 typed from the paper, the valve chain of Eq. 4 and 9 by Runge-Kutta steps behind the
delay of Eq. 10, the friction planes and Eq. 15/18, Eq. 13), taking from the model only the
parameters' names and values, and, switched on at will, real effects in other
functional forms than the model's candidates, and effects on no list, each with its own
equations (in the docstrings of ``valve``, ``passages``, ``chambers``, ``mechanics`` and
``sensors``). Its
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
