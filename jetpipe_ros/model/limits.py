"""What values the actuator's signals can physically take: bounds for data and for inputs.

The bounds are generous (a measurement just outside them is impossible for this actuator, not
merely unusual) and follow from the model's parameters where those set them:

- absolute pressure in [0.1, 20] bar: nothing below a tenth of the atmosphere (the valve vents to
  it), nothing above twice the 10 bar supply;
- position within the stroke's end stops plus 1 mm (sensor noise is 15 um);
- velocity within 10 m/s (full supply pressure accelerates the nominal 1 kg piston through
  its 50 mm stroke to about 3 m/s at most);
- valve command within 10 V (a servo amplifier's input range; the valve saturates at 3.4 V);
- external load within :data:`LOAD_FACTOR` times the largest pneumatic force
  S (p_s - p_atm) (4.9 kN nominal, so 19.6 kN), which also bounds the simulator's load input.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from jetpipe_ros.model.flow import P_ATM, P_SUPPLY_NOMINAL

#: The load bound as a multiple of the largest pneumatic force S (p_s - p_atm).
LOAD_FACTOR = 4.0
#: Allowance beyond the end stops for position data [m].
POSITION_MARGIN = 1e-3


def load_limit(params: Mapping[str, Any]) -> float:
    """Largest plausible external load |F_L| [N]: LOAD_FACTOR x S (p_s - p_atm)."""
    return LOAD_FACTOR * params["chamber.piston_area"] * (P_SUPPLY_NOMINAL - P_ATM)


@dataclass(frozen=True)
class Limits:
    """Plausible ranges of the dataset signals (SI units; pressures absolute)."""

    pressure: tuple[float, float] = (1.0e4, 2.0e6)  #: absolute pressure [Pa]
    #: where a whole pressure record lies on a working actuator [Pa] (unit guesses)
    pressure_typical: tuple[float, float] = (0.8e5, 1.2e6)
    position: float = 0.025 + POSITION_MARGIN  #: largest |y| [m]
    velocity: float = 10.0  #: largest |v| [m/s]
    voltage: float = 10.0  #: largest |u| [V]
    load: float = LOAD_FACTOR * 0.005433 * (P_SUPPLY_NOMINAL - P_ATM)  #: largest |F_L| [N]
    sample_time: tuple[float, float] = (1e-5, 0.1)  #: median sample interval [s]

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> Limits:
        """The limits of an actuator with parameters ``params`` (stroke, piston area)."""
        return cls(position=params["mechanics.stroke"] / 2 + POSITION_MARGIN,
                   load=load_limit(params))


#: The nominal actuator's limits (docs/model.md).
NOMINAL = Limits()
