"""Records of a pneumatic actuator the package's model does NOT describe (issue 22), for tests.

A self-contained simulator of other hardware: a single-acting, spring-return cylinder pushed by
one chamber, fed and vented by two on/off solenoid valves. Its equations are its own; nothing of
the package's model is used (only :func:`jetpipe_ros.dataset.write_dataset` and ``Entry`` to
write the records). Run it to write a dataset and a parameter file a person can look at::

    python test/foreign_hardware.py OUT_DIR [--seed N]

The rig
-------
x [m] is the piston's travel from the retracted end stop, 0 <= x <= L (L = stroke); the records
give y = x - L/2 [m], centred on mid-stroke. Chamber 1 (cap end) pushes the piston out; the rod
side is open to the atmosphere; a return spring pushes the piston in.

Mechanics (Newton, [N]), moving mass m [kg]::

    m dv/dt = (p1 - p_atm) A - (F0 + k x) - c v - F_C sign(v)          while sliding
    v = 0, x held                  while |(p1 - p_atm) A - (F0 + k x)| <= F_S (stiction)

with A = pi D^2 / 4 [m^2] the bore's area, k [N/m] and F0 [N] the spring rate and preload at
x = 0, c [N s/m] viscous and F_C [N] Coulomb friction, F_S [N] the breakaway force. The end
stops at x = 0 and x = L are hard and inelastic (v -> 0 on impact); the piston leaves one only
when the net force pulls it away by more than F_S. The hybrid system (sliding up, sliding down,
stuck) is integrated by ``scipy.integrate.solve_ivp`` (RK45) with terminal events at v = 0, at
the end stops and at the breakaway thresholds.

Chamber 1 (mass and energy balance, Richer & Hurmuzlu's form [Pa/s]), volume
V1 = V0 + A x [m^3] with V0 the dead volume (cap end, port, hose)::

    dp1/dt = R T / V1 (a_in q_in - a_out q_out) - a p1 A v / V1

q_in, q_out [kg/s] >= 0 the mass flows into and out of the chamber, R = 287 J/(kg K), T [K]
the supply air temperature, a_in = 1.4 (adiabatic charging), a_out = 1.0, a = 1.2 (polytropic
compression by the piston).

Valves: two 2/2 normally closed solenoid valves, fill (supply p_s -> chamber) and vent
(chamber -> atmosphere), each an orifice after ISO 6358 with sonic conductance C
[m^3/(s Pa)] and critical pressure ratio b::

    q = C rho0 p_up sqrt(T0 / T)                                  r = p_down / p_up <= b
    q = C rho0 p_up sqrt(T0 / T) sqrt(1 - ((r - b) / (1 - b))^2)  b < r <= 1

with rho0 = 1.185 kg/m^3, T0 = 293.15 K (ISO 8778 reference air). Above r = 0.999 the flow is
continued linearly to zero at r = 1 (the laminar end of ISO 6358-3), which keeps dp/dt Lipschitz.
A valve opens ``pull_in`` [s] after its coil is energised and closes ``drop_out`` [s] after it is
released; a shorter pulse does not move the armature.

Driver: command u [V] at 1 kHz; u > +1 V energises the fill valve, u < -1 V the vent valve,
otherwise both are closed (the chamber holds its air).

Sensors: position with Gaussian noise 15 um, chamber 1 pressure (absolute) with 500 Pa; there is
no second chamber pressure. Row k of a record is the state at t_k = k dt and the command u_k
computed from the measurement at t_k, held over [t_k, t_k+1).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from jetpipe_ros.dataset import Entry, write_dataset

R_AIR = 287.0  #: specific gas constant of air [J/(kg K)]
RHO0 = 1.185  #: ISO 8778 reference density [kg/m^3]
T0 = 293.15  #: ISO 8778 reference temperature [K]
P_ATM = 101325.0  #: atmosphere [Pa]
LAMINAR_RATIO = 0.999  #: pressure ratio above which the orifice flow is continued linearly
DT = 1e-3  #: sample time [s]
THRESHOLD = 1.0  #: driver threshold [V]


@dataclass(frozen=True)
class Rig:
    """The foreign rig's physical parameters (SI units, pressures absolute)."""

    bore: float = 0.025  #: piston diameter D [m] (ISO 6432 size 25)
    rod: float = 0.010  #: rod diameter [m] (the rod side is vented; for the record only)
    stroke: float = 0.050  #: L [m]
    dead_volume: float = 5.0e-6  #: V0 [m^3]: cap end 1.2 cm^3 + 0.3 m of 4 mm hose 3.8 cm^3
    rod_side_volume: float = 2.0e-6  #: port volume of the vented rod side [m^3] (params file)
    mass: float = 0.25  #: moving mass m [kg]: piston, rod, clevis and a small tool
    spring_rate: float = 600.0  #: k [N/m]
    spring_preload: float = 20.0  #: F0 [N] at x = 0 (50 N at full stroke)
    coulomb: float = 6.0  #: F_C [N]
    breakaway: float = 8.0  #: F_S [N]
    viscous: float = 25.0  #: c [N s/m]
    supply: float = P_ATM + 6.0e5  #: p_s [Pa]: 6 bar gauge
    temperature: float = 293.15  #: T [K]
    fill_conductance: float = 6.0e-10  #: C of the fill valve [m^3/(s Pa)] (0.06 dm^3/(s bar))
    fill_ratio: float = 0.40  #: b of the fill valve
    vent_conductance: float = 8.0e-10  #: C of the vent valve [m^3/(s Pa)] (0.08 dm^3/(s bar))
    vent_ratio: float = 0.35  #: b of the vent valve
    pull_in: float = 0.004  #: valve opening delay [s]
    drop_out: float = 0.002  #: valve closing delay [s]
    alpha_in: float = 1.4  #: a_in
    alpha_out: float = 1.0  #: a_out
    alpha: float = 1.2  #: a (piston work)
    position_sigma: float = 15e-6  #: [m]
    pressure_sigma: float = 500.0  #: [Pa]

    @property
    def area(self) -> float:
        """A [m^2]."""
        return math.pi * self.bore ** 2 / 4.0


def iso6358(p_up: float, p_down: float, conductance: float, ratio: float,
            temperature: float) -> float:
    """Mass flow [kg/s] from ``p_up`` to ``p_down`` [Pa] through an ISO 6358 orifice (negative
    when p_down > p_up: the orifice is symmetric)."""
    if p_up < p_down:
        return -iso6358(p_down, p_up, conductance, ratio, temperature)
    choked = conductance * RHO0 * p_up * math.sqrt(T0 / temperature)
    r = p_down / p_up
    if r <= ratio:
        return choked
    if r <= LAMINAR_RATIO:
        return choked * math.sqrt(1.0 - ((r - ratio) / (1.0 - ratio)) ** 2)
    edge = math.sqrt(1.0 - ((LAMINAR_RATIO - ratio) / (1.0 - ratio)) ** 2)
    return choked * edge * (1.0 - r) / (1.0 - LAMINAR_RATIO)


class Cylinder:
    """The rig's continuous state (x, v, p1), its friction mode and the two valves."""

    def __init__(self, rig: Rig, x: float = 0.0, p1: float = P_ATM) -> None:
        self.rig = rig
        self.state = np.array([x, 0.0, p1])
        self.mode = 0  # +1 sliding out, -1 sliding in, 0 stuck (at rest)
        self.fill_open = False
        self.vent_open = False
        self.mode = self._release(self.state)

    # -- physics --
    def _static_force(self, s: np.ndarray) -> float:
        """Net force on the piston at rest [N]: pressure minus spring."""
        rig = self.rig
        return (s[2] - P_ATM) * rig.area - (rig.spring_preload + rig.spring_rate * s[0])

    def _pressure_rate(self, x: float, v: float, p1: float, fill: bool, vent: bool) -> float:
        rig = self.rig
        q = 0.0
        if fill:
            q += iso6358(rig.supply, p1, rig.fill_conductance, rig.fill_ratio, rig.temperature)
        if vent:
            q -= iso6358(p1, P_ATM, rig.vent_conductance, rig.vent_ratio, rig.temperature)
        gain = rig.alpha_in if q > 0.0 else rig.alpha_out
        vol = rig.dead_volume + rig.area * x
        return (R_AIR * rig.temperature * gain * q - rig.alpha * p1 * rig.area * v) / vol

    def _rhs(self, mode: int, fill: bool, vent: bool) -> Callable[[float, np.ndarray], list]:
        rig = self.rig

        def f(_t: float, s: np.ndarray) -> list:
            x, v, p1 = s
            dp = self._pressure_rate(x, v, p1, fill, vent)
            if mode == 0:
                return [0.0, 0.0, dp]
            force = self._static_force(s) - rig.viscous * v - rig.coulomb * mode
            return [v, force / rig.mass, dp]
        return f

    def _events(self, mode: int, x: float) -> list:
        rig = self.rig
        events = []
        if mode != 0:
            def stop(_t, s):  # velocity back to zero
                return s[1]
            stop.direction = -mode
            events.append(stop)
            if mode > 0:
                def end(_t, s):
                    return s[0] - rig.stroke
                end.direction = 1
            else:
                def end(_t, s):
                    return s[0]
                end.direction = -1
            events.append(end)
        else:
            if x < rig.stroke:
                def out(_t, s):
                    return self._static_force(s) - rig.breakaway
                out.direction = 1
                events.append(out)
            if x > 0.0:
                def back(_t, s):
                    return self._static_force(s) + rig.breakaway
                back.direction = -1
                events.append(back)
        for e in events:
            e.terminal = True
        return events

    def _release(self, s: np.ndarray) -> int:
        """The mode of a piston at rest in state ``s``: stuck, or breaking away."""
        f = self._static_force(s)
        if f > self.rig.breakaway and s[0] < self.rig.stroke:
            return 1
        if f < -self.rig.breakaway and s[0] > 0.0:
            return -1
        return 0

    def _after_event(self, s: np.ndarray, kind: str) -> int:
        s[1] = 0.0
        if kind == "end":
            s[0] = min(max(s[0], 0.0), self.rig.stroke)
            return self._release(s)
        if kind == "stop":
            # v reached 0 while sliding: reverse only if the force beats the breakaway
            return self._release(s)
        # breakaway from rest
        return 1 if kind == "out" else -1

    def advance(self, t0: float, t1: float) -> list[tuple]:
        """Integrate from t0 to t1 with the valves as they are; return the pieces
        (start, end, friction mode, state(t)) covering [t0, t1]."""
        pieces = []
        t = t0
        for _ in range(10000):
            if t >= t1 - 1e-12:
                break
            mode, s = self.mode, self.state
            events = self._events(mode, s[0])
            sol = solve_ivp(self._rhs(mode, self.fill_open, self.vent_open), (t, t1), s,
                            method="RK45", rtol=1e-7, atol=[1e-9, 1e-7, 1e-2],
                            events=events, dense_output=True)
            if sol.status < 0:
                raise RuntimeError(f"integration failed at t = {t}: {sol.message}")
            t_end = sol.t[-1]
            if t_end > t:
                pieces.append((t, t_end, mode, sol.sol))
            new = sol.y[:, -1].copy()
            if sol.status == 1:
                hit = next(i for i, te in enumerate(sol.t_events) if te.size)
                kind = events[hit].__name__
                self.mode = self._after_event(new, kind)
            if self.mode == 0:
                new[1] = 0.0
            self.state, t = new, t_end
        else:
            raise RuntimeError(f"too many friction mode switches near t = {t}")
        return pieces


@dataclass
class Valve:
    """A solenoid valve's armature: opens ``pull_in`` samples after its coil is energised and
    closes ``drop_out`` samples after it is released."""

    pull_in: int
    drop_out: int
    open: bool = False
    count: int = 0

    def update(self, coil: bool) -> bool:
        """The valve's state over the next sample with the coil as given."""
        if coil == self.open:
            self.count = 0
            return self.open
        self.count += 1
        if self.count > (self.pull_in if coil else self.drop_out):
            self.open, self.count = coil, 0
        return self.open


Controller = Callable[[int, float, float, float], float]  # (k, t, y_meas, p1_meas) -> u


def simulate(rig: Rig, controller: Controller, duration: float,
             rng: np.random.Generator | None = None, x0: float = 0.0,
             p0: float = P_ATM, horizon: float = 0.2) -> dict[str, np.ndarray]:
    """Run the rig for ``duration`` [s] under ``controller``; return the record's columns
    t, u, y, p1 (measured, with noise when ``rng`` is given) and the true x, v, p_true and the
    valve states fill, vent over each sample.

    Between valve switchings the hybrid ODE is integrated once, with dense output, up to
    ``horizon`` [s] ahead; the controller is evaluated at every sample on that solution, and the
    integration restarts from the first sample whose valve state differs.
    """
    n = int(round(duration / DT))
    cyl = Cylinder(rig, x0, p0)
    fill = Valve(round(rig.pull_in / DT), round(rig.drop_out / DT))
    vent = Valve(round(rig.pull_in / DT), round(rig.drop_out / DT))
    out = {k: np.zeros(n) for k in ("t", "u", "y", "p1", "x", "v", "p_true", "fill", "vent")}
    noise = rng.standard_normal((n, 2)) if rng is not None else np.zeros((n, 2))
    pieces: list = []
    block_valves = None
    block_end = 0  # sample at which the current block's integration ends
    state, mode = cyl.state.copy(), cyl.mode
    for j in range(n):
        t = j * DT
        if j > 0:
            if j >= block_end:
                state, mode = cyl.state.copy(), cyl.mode
            else:
                state, mode = _evaluate(pieces, t)
        out["t"][j] = t
        out["x"][j], out["v"][j], out["p_true"][j] = state
        y = state[0] - rig.stroke / 2 + rig.position_sigma * noise[j, 0]
        p = state[2] + rig.pressure_sigma * noise[j, 1]
        out["y"][j], out["p1"][j] = y, p
        u = float(np.clip(controller(j, t, y, p), -10.0, 10.0))
        out["u"][j] = u
        valves = (fill.update(u > THRESHOLD), vent.update(u < -THRESHOLD))
        out["fill"][j], out["vent"][j] = valves
        if j == n - 1:
            break
        if valves != block_valves or j >= block_end:
            # (re)start the integration at t_j with these valves
            cyl.state, cyl.mode = state.copy(), mode
            cyl.fill_open, cyl.vent_open = valves
            block_valves = valves
            block_end = min(n - 1, j + max(1, int(round(horizon / DT))))
            pieces = cyl.advance(t, block_end * DT)
    return out


def _evaluate(pieces: list, t: float) -> tuple[np.ndarray, int]:
    """State and friction mode at ``t`` from the pieces of one integration (the later piece at
    a boundary: the mode after an event)."""
    for start, stop, mode, sol in reversed(pieces):
        if start - 1e-12 <= t <= stop + 1e-12:
            s = sol(t)
            if mode == 0:
                s[1] = 0.0
            return s, mode
    raise RuntimeError(f"no solution piece covers t = {t}")


# -- the experiments --

def bang_bang(setpoint: Callable[[float], float], gain: float = 1000.0,
              limit: float = 8.0) -> Controller:
    """A proportional position controller saturated at +-``limit`` [V] whose on/off driver makes
    it bang-bang with a dead band of THRESHOLD / gain (1 mm): u = clip(gain (r - y))."""
    def control(_k: int, t: float, y: float, _p: float) -> float:
        return float(np.clip(gain * (setpoint(t) - y), -limit, limit))
    return control


def square_setpoint(t: float) -> float:
    """Steps every 0.5 s, two of them beyond the end stops (fill or vent held open)."""
    levels = (-0.030, 0.0, 0.015, 0.030, -0.012, -0.030, 0.020, 0.005)
    return levels[min(int(t / 0.5), len(levels) - 1)]


def sine_setpoint(t: float) -> float:
    """A slow sine over most of the stroke."""
    return 0.003 + 0.019 * math.sin(2 * math.pi * 0.6 * t - math.pi / 2)


def pulse_train(rng: np.random.Generator, duration: float) -> Controller:
    """Open loop: a 25 Hz PWM (fill for duty d, vent for the rest of the period's first 70 %)
    with d sweeping 0.1..0.6, then random pulses 5..120 ms of +-8 V or 0 V."""
    n = int(round(duration / DT))
    u = np.zeros(n)
    k = 0
    half = n // 2
    period = 40
    while k < half:
        d = 0.1 + 0.5 * (0.5 - 0.5 * math.cos(2 * math.pi * k / half))
        on = int(round(d * period))
        vent_end = max(on, int(round(0.7 * period)))
        u[k:min(k + on, half)] = 8.0
        u[k + on:min(k + vent_end, half)] = -8.0
        k += period
    while k < n:
        width = int(rng.integers(5, 121))
        u[k:k + width] = rng.choice([8.0, 0.0, -8.0], p=[0.4, 0.2, 0.4])
        k += width

    def control(k: int, _t: float, _y: float, _p: float) -> float:
        return float(u[k])
    return control


def experiments(seed: int = 0, rig: Rig | None = None) -> list[tuple[Entry, dict]]:
    """The three records: (entry, columns t, u, y, p1) in dataset order."""
    rig = rig or Rig()
    rng = np.random.default_rng(seed)
    runs = [
        (Entry("track_square.csv", role="train"), bang_bang(square_setpoint), 4.0),
        (Entry("pwm_pulses.csv", role="train"), pulse_train(rng, 3.0), 3.0),
        (Entry("track_sine.csv", role="holdout"), bang_bang(sine_setpoint), 3.0),
    ]
    out = []
    for entry, controller, duration in runs:
        rec = simulate(rig, controller, duration, rng)
        out.append((entry, {k: rec[k] for k in ("t", "u", "y", "p1")}))
    return out


def write_foreign_dataset(root: Path, seed: int = 0) -> Path:
    """Write the foreign rig's 10 s dataset (dataset.yaml and three CSVs t,u,y,p1, the last
    ``role: holdout``) to ``root``; return it."""
    return write_dataset(Path(root), experiments(seed), overwrite=True)


def write_foreign_params(path: Path, rig: Rig | None = None) -> Path:
    """Write the package's parameter YAML (ROS layout) giving this rig's geometry and mass."""
    rig = rig or Rig()
    half = rig.stroke / 2
    text = f"""\
# The foreign rig of test/foreign_hardware.py: a single-acting spring-return cylinder, bore
# {rig.bore * 1e3:g} mm, stroke {rig.stroke * 1e3:g} mm, one chamber fed and vented by on/off
# solenoid valves at {(rig.supply - P_ATM) / 1e5:g} bar gauge. Only what the package's model can
# take of it: geometry, moving mass, initial state, sensors. Chamber 2 is the vented rod side:
# its volume at mid-stroke is the half stroke swept by the (full-bore) area plus its port.
actuator_sim:
  ros__parameters:
    chamber:
      piston_area: {rig.area:.6g}  # [m^2] pi D^2 / 4
      dead_volume_1: {rig.dead_volume + rig.area * half:.6g}  # [m^3] cap end at y = 0
      dead_volume_2: {rig.rod_side_volume + rig.area * half:.6g}  # [m^3] rod side at y = 0
      temperature: {rig.temperature:g}  # [K]
      initial_pressure_1: {P_ATM:g}  # [Pa] records start vented
      initial_pressure_2: {P_ATM:g}  # [Pa]
    mechanics:
      mass: {rig.mass:g}  # [kg]
      stroke: {rig.stroke:g}  # [m]
      initial_position: {-half:g}  # [m] records start retracted
    sensors:
      position_sigma: {rig.position_sigma:g}  # [m]
      pressure_sigma: {rig.pressure_sigma:g}  # [Pa]
"""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="directory to write dataset/ and params.yaml to")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    data = write_foreign_dataset(args.out / "dataset", args.seed)
    params = write_foreign_params(args.out / "params.yaml")
    print(f"wrote {data} and {params}")
    return 0


if __name__ == "__main__":
    sys.exit(main())


__all__ = ["Cylinder", "Rig", "iso6358", "simulate", "write_foreign_dataset",
           "write_foreign_params"]
