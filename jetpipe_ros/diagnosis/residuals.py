"""Equation errors: what each equation of a model leaves unexplained in recorded data, and a
sparse description of their shape.

When no candidate explains a gap, the missing physics is located by asking each equation of the
(recalibrated) model what it leaves over, sample by sample, with every state taken from the
measurements (smoothed, zero phase) rather than simulated:

- **chamber 1 and chamber 2 mass balance** (Eq. 8, 11-13 with the model's effects, the rates
  the kernel integrates: :func:`kernel.chamber_rates`): the measured pressure rate against the
  model's rate at the measured pressures, position, velocity and the equivalent valve voltage
  the model's valve chain makes of the recorded command (the gas taken at the wall temperature,
  which is not measured); expressed as an equivalent mass flow into the chamber [kg/s] (rate
  error x V / (r T));
- **force balance** (Eq. 14 with Eq. 15-18) while the piston slides: the measured acceleration
  times the mass against the pneumatic force, the load and the friction at the measured states
  [N].

Errors and terms are averaged over 50-ms blocks (the noise of the derivatives falls, the missing
physics stays). The part of each error that has the shape of a calibration knob (a flow-map or
valve gain error, a dead volume, a friction level) is removed by least squares: it is a mis-set
parameter, not missing physics. What remains is compared with the same on the noise twin of the
dataset (the model itself re-measured with the sensor noise, :mod:`noise_floor`): the ratio of
their RMS says which equation holds a gap beyond noise that no recalibration explains. The error
is then regressed on a small library of terms that each name a physical shape and the subsystem
it belongs to (a constant, an offset in the valve command, a flow gain that changes with chamber
pressure, a leak across the piston or to atmosphere, a force near the end stops, ...), with a
sparse linear model whose number of terms is chosen by the Bayesian information criterion
(scikit-learn's ``LassoLarsIC``). The terms that carry the error describe the missing physics in
words, with the operating regime where the error is largest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter
from sklearn.linear_model import LassoLarsIC

from jetpipe_ros.diagnosis.data import Prepared, Record
from jetpipe_ros.diagnosis.localize import REGIMES, regimes
from jetpipe_ros.model import Actuator, ModelParams, build_constants, kernel
from jetpipe_ros.model.chamber import chamber_volumes
from jetpipe_ros.model.flow import P_ATM
from jetpipe_ros.model.friction import scaled_parameters, stribeck_force

#: Sliding: |v| above this [m/s] (the force balance is indeterminate while stuck).
SLIDING = 5e-3
#: Savitzky-Golay window of the derivatives [s] (zero phase, quadratic).
WINDOW = 0.021
#: End-stop zone of the library's cushion terms: the last 3 mm of stroke [m].
CUSHION = 3e-3
#: Errors and library terms are averaged over blocks of this length [s] before they are
#: compared and regressed: sensor noise (white, through the derivatives) falls as
#: 1/sqrt(samples per block) while the physics the model misses, slower than 50 ms, stays.
BLOCK = 0.05
#: An equation error whose blocked RMS exceeds the noise twin's by this factor holds a gap: a
#: systematic part at least as large as the noise left in it (sqrt(1 + 1)).
BEYOND_NOISE = float(np.sqrt(2.0))
#: Library terms that carry less than this share of an error's variance are not described.
LEAST_SHARE = 0.1

EQUATIONS = ("chamber 1 mass balance", "chamber 2 mass balance", "force balance")
_SUBSYSTEM_OF_EQUATION = {"chamber 1 mass balance": "valve+chamber",
                          "chamber 2 mass balance": "valve+chamber",
                          "force balance": "mechanics"}


@dataclass
class Term:
    """One library term: what its shape means, the subsystem it points to, its values, and
    whether it is the shape of a calibration knob (a mis-set nominal parameter, not missing
    physics)."""

    name: str
    meaning: str
    subsystem: str
    values: np.ndarray
    calibration: bool = False


@dataclass
class EquationError:
    """One equation's error over the dataset, with its library and the noise twin's RMS."""

    equation: str
    unit: str
    error: np.ndarray  #: the error on the samples used [unit]
    regime: dict[str, np.ndarray]  #: regime masks over the same samples
    terms: list[Term]
    noise_rms: float = 0.0  #: RMS of the same error on the noise twin [unit]

    @property
    def rms(self) -> float:
        """RMS of the error [unit]."""
        return float(np.sqrt(np.mean(self.error ** 2))) if self.error.size else 0.0

    @property
    def over_noise(self) -> float:
        """RMS of the error over the noise twin's."""
        return self.rms / self.noise_rms if self.noise_rms > 0 else 0.0


def _derivative(x: np.ndarray, dt: float, order: int) -> np.ndarray:
    n = max(5, int(round(WINDOW / dt)) | 1)
    if x.size < n:
        return np.gradient(x, dt) if order == 1 else np.gradient(np.gradient(x, dt), dt)
    return savgol_filter(x, n, 2, deriv=order, delta=dt)


def _pressure_rate(rec: Record, chamber: int, dt: float) -> np.ndarray:
    """The measured pressure rate of chamber 1 or 2 [Pa/s]; NaN where it was not measured."""
    name = f"p{chamber}"
    if not rec.measured(name):
        return np.full(rec.t.size, np.nan)
    return _derivative(rec.signal(name), dt, 1)


def _equivalent_voltage(params: ModelParams, rec: Record, dt: float) -> np.ndarray:
    """The model's equivalent valve voltage u_eq [V] for the recorded command, sample by sample
    (the valve chain with its delay, lags and hysteresis; chambers and piston held on the
    measurements, which the chain does not depend on)."""
    act = Actuator(params.at_sample_time(dt).with_values({"mechanics.locked": rec.locked,
                                                          "sensors.noise": False}))
    n = rec.t.size
    drive = np.column_stack([rec.smooth["y"], rec.v, rec.smooth["p1"], rec.smooth["p2"]])
    out = act.run(rec.u, rec.f_load, drive)
    # Row k is the end of sample k: the voltage acting over [t_k, t_k+1).
    return np.concatenate([out[:-1, kernel.OUT_UEQ], out[-1:, kernel.OUT_UEQ]])[:n]


def chamber_errors(params: ModelParams, rec: Record, dt: float) -> tuple[np.ndarray, ...]:
    """Mass-balance errors of chambers 1 and 2 [kg/s equivalent] at every sample, and the
    model's inflows q1, q2 [kg/s] and flow sensitivities dq/du [kg/(s V)] there."""
    c = build_constants(params.at_sample_time(dt))  # rows dt apart (the supply line's state)
    u_eq = _equivalent_voltage(params, rec, dt)
    y = rec.smooth["y"] if not rec.locked else np.full(rec.t.size, rec.smooth["y"][0])
    v = rec.v
    p1, p2 = rec.smooth["p1"], rec.smooth["p2"]
    dp1, dp2 = _pressure_rate(rec, 1, dt), _pressure_rate(rec, 2, dt)
    rates = kernel.chamber_rates(c, y, v, p1, p2, u_eq)
    vol1, vol2 = chamber_volumes(y, c.area, c.v01, c.v02)
    e1 = (dp1 - rates[0]) * vol1 / c.rt
    e2 = (dp2 - rates[1]) * vol2 / c.rt
    return e1, e2, rates[2], rates[3], rates[4], rates[5], u_eq


def force_error(params: ModelParams, rec: Record, dt: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Force-balance error [N] while sliding, the mask of sliding samples, and the model's
    Stribeck (scaled by the bore profile at the measured position) and viscous friction there
    [N]."""
    c = build_constants(params)
    y = rec.smooth["y"]
    v = rec.v
    a = _derivative(rec.y, dt, 2)
    p1, p2 = rec.smooth["p1"], rec.smooth["p2"]
    sliding = (np.abs(v) > SLIDING) & (np.abs(y) < c.y_max)
    err = np.zeros(rec.t.size)
    static = np.zeros(rec.t.size)
    viscous = np.zeros(rec.t.size)
    for k in np.flatnonzero(sliding):
        f_s, v_s, f_v, f_c = scaled_parameters(c.planes, c.profile, np.sign(v[k]), y[k],
                                               p1[k], p2[k], c.friction_floor)
        static[k] = stribeck_force(v[k], f_s, v_s, f_c)
        viscous[k] = f_v * v[k]
        err[k] = c.mass * a[k] - (c.area * (p1[k] - p2[k]) - rec.f_load[k] - static[k]
                                  - viscous[k])
    return err, sliding, static, viscous


def _chamber_terms(i: int, p: np.ndarray, p_other: np.ndarray, dp: np.ndarray, q: np.ndarray,
                   dqdu: np.ndarray, u_eq: np.ndarray, v: np.ndarray, area: float,
                   rt: float, p_supply: float) -> list[Term]:
    sign = 1.0 if i == 1 else -1.0
    mid = 0.5 * (p_supply + P_ATM)
    return [
        Term("constant", f"a constant flow into chamber {i}", "valve+chamber",
             np.ones_like(p)),
        Term("valve offset", "an offset in the valve command (the flow map's null shifted)",
             "valve", dqdu),
        Term("valve gain", "a valve gain error (flow error proportional to the command's "
             "effect)", "valve", u_eq * dqdu, calibration=True),
        Term("flow scale", "a flow-map gain error (flow error proportional to the flow)",
             "valve", q, calibration=True),
        Term("flow scale filling", "a flow-map gain error where the flow fills the chamber",
             "valve", np.maximum(q, 0.0), calibration=True),
        Term("flow x pressure", f"a flow-map gain that changes with chamber {i}'s pressure",
             "valve", q * (p - mid) / (p_supply - P_ATM)),
        Term("leak to atmosphere", f"a flow out of chamber {i} that grows with its pressure "
             f"above atmosphere", "chamber", -(p - P_ATM) * 1e-10),
        Term("leak across the piston", "a flow from the higher-pressure chamber to the other",
             "chamber", -(p - p_other) * 1e-10),
        Term("compression", f"a term with the volume change of chamber {i} (non-isothermal "
             f"gas)", "chamber", -sign * area * p * v / rt),
        Term("dead volume", f"a term with chamber {i}'s pressure rate (its volume, or the gas "
             f"stiffness, other than the model's)", "chamber", dp / rt, calibration=True),
    ]


def _force_terms(y: np.ndarray, v: np.ndarray, a: np.ndarray, dp: np.ndarray, area: float,
                 y_max: float, static: np.ndarray, viscous: np.ndarray) -> list[Term]:
    zone = np.maximum(np.abs(y) - (y_max - CUSHION), 0.0) * np.sign(y)
    entry, exit_ = v < 0.0, v > 0.0
    return [
        *(Term(f"friction level {ph}", f"the {ph}-phase breakaway and Coulomb friction "
               f"off", "mechanics", static * m, calibration=True)
          for ph, m in (("entry", entry), ("exit", exit_))),
        *(Term(f"viscous level {ph}", f"the {ph}-phase viscous friction off", "mechanics",
               viscous * m, calibration=True) for ph, m in (("entry", entry), ("exit", exit_))),
        Term("constant", "a constant force on the piston", "mechanics", np.ones_like(y)),
        Term("viscous", "a force proportional to the velocity", "mechanics", v),
        Term("coulomb", "a constant force against the motion", "mechanics", np.sign(v)),
        Term("pneumatic scale", "a force proportional to the pressure difference (area)",
             "mechanics", area * dp),
        Term("inertia", "a force proportional to the acceleration (mass)", "mechanics", a),
        Term("spring", "a force proportional to the position (a spring)", "mechanics", y),
        Term("end-stop spring", "a force that grows in the last 3 mm of stroke (cushioning)",
             "mechanics", zone),
        Term("end-stop damping", "a force against the motion in the last 3 mm of stroke",
             "mechanics", v * (zone != 0.0)),
    ]


def _blocks(x: np.ndarray, n: int) -> np.ndarray:
    """Means of consecutive blocks of ``n`` samples (a trailing partial block dropped)."""
    m = x.size // n
    return x[:m * n].reshape(m, n).mean(axis=1) if m else x[:0].astype(float)


def equation_errors(prepared: Prepared, params: ModelParams,
                    stroke: float) -> list[EquationError]:
    """The three equation errors over all experiments, averaged over :data:`BLOCK`-long blocks,
    with their libraries and regimes (a block is in a regime when most of its samples are)."""
    parts: dict[str, dict[str, list]] = {e: {"err": [], "terms": [], "reg": []}
                                         for e in EQUATIONS}
    c = build_constants(params)
    dt = prepared.dt
    n = max(int(round(BLOCK / dt)), 1)

    def add(eq: str, err: np.ndarray, terms: list[Term], reg: dict, keep: np.ndarray) -> None:
        d = parts[eq]
        d["err"].append(_blocks(err[keep], n))
        d["terms"].append([Term(t.name, t.meaning, t.subsystem, _blocks(t.values[keep], n),
                                t.calibration) for t in terms])
        d["reg"].append({k: _blocks(m[keep].astype(float), n) > 0.5 for k, m in reg.items()})

    for rec in prepared.records:
        reg = regimes(rec, dt, stroke)
        everywhere = np.ones(rec.t.size, dtype=bool)
        # An equation is asked only where the record measured every state it holds (a chamber's
        # own pressure and the position; the force balance both pressures).
        if not rec.regulated and rec.measured("y") and (rec.measured("p1")
                                                        or rec.measured("p2")):
            e1, e2, q1, q2, g1, g2, u_eq = chamber_errors(params, rec, dt)
            p1, p2 = rec.smooth["p1"], rec.smooth["p2"]
            dp1, dp2 = _pressure_rate(rec, 1, dt), _pressure_rate(rec, 2, dt)
            for i, e, p, po, dp, q, g in ((1, e1, p1, p2, dp1, q1, g1),
                                          (2, e2, p2, p1, dp2, q2, g2)):
                if not rec.measured(f"p{3 - i}"):
                    po = p  # the other chamber unmeasured: no leak across the piston to see
                terms = _chamber_terms(i, p, po, dp, q, g, u_eq, rec.v, c.area, c.rt,
                                       c.p_supply)
                keep = np.isfinite(e) & np.all([np.isfinite(t.values) for t in terms], axis=0)
                if rec.measured(f"p{i}") and keep.any():
                    add(EQUATIONS[i - 1], e, terms, reg, keep & everywhere)
        if not rec.locked and all(rec.measured(s) for s in ("y", "p1", "p2")):
            err, sliding, static, viscous = force_error(params, rec, dt)
            a = _derivative(rec.y, dt, 2)
            add("force balance", err, _force_terms(rec.smooth["y"], rec.v, a,
                                                   rec.smooth["p1"] - rec.smooth["p2"],
                                                   c.area, c.y_max, static, viscous),
                reg, sliding)
    out = []
    for eq, d in parts.items():
        if not d["err"]:
            continue
        terms = [Term(t.name, t.meaning, t.subsystem,
                      np.concatenate([ts[j].values for ts in d["terms"]]), t.calibration)
                 for j, t in enumerate(d["terms"][0])]
        regime = {r: np.concatenate([rg.get(r, np.zeros(e.size, dtype=bool))
                                     for rg, e in zip(d["reg"], d["err"])]) for r in REGIMES}
        unit = "N" if eq == "force balance" else "kg/s"
        out.append(EquationError(eq, unit, np.concatenate(d["err"]), regime, terms))
    return out


def without_calibration(err: EquationError) -> EquationError:
    """The error less what the calibration knobs' shapes explain (least squares on the
    calibration terms): what no recalibration could remove."""
    cal = [t.values for t in err.terms if t.calibration]
    rest = [t for t in err.terms if not t.calibration]
    e = err.error
    if cal and e.size > len(cal):
        x = np.column_stack(cal)
        coef, *_ = np.linalg.lstsq(x, e, rcond=None)
        e = e - x @ coef
    return EquationError(err.equation, err.unit, e, err.regime, rest, err.noise_rms)


def sparse_terms(err: EquationError) -> list[dict]:
    """The library terms that carry the error (sparse regression, terms chosen by BIC), each
    with the share of the error's mean square it explains alone (its squared correlation with
    the error; the constant: the squared mean), best first."""
    if err.error.size < 20:
        return []
    x = np.column_stack([t.values for t in err.terms])
    scale = x.std(axis=0)
    keep = scale > 0
    xs = (x[:, keep] - x[:, keep].mean(axis=0)) / scale[keep]
    terms = [t for t, k in zip(err.terms, keep) if k]
    e = err.error
    y = e - e.mean()
    model = LassoLarsIC(criterion="bic").fit(xs, y)
    total = float(np.mean(e ** 2)) or 1.0
    rows = []
    for coef, col, term in zip(model.coef_, xs.T, terms):
        if coef != 0.0:
            rows.append({"term": term.name, "meaning": term.meaning,
                         "subsystem": term.subsystem,
                         "coefficient": float(coef / term.values.std()),
                         "share": float(np.mean(col * y) ** 2 / total)})
    const = next((t for t, k in zip(err.terms, keep) if not k), None)
    if const is not None:  # the constant term: the error's mean
        rows.append({"term": const.name, "meaning": const.meaning,
                     "subsystem": const.subsystem, "coefficient": float(e.mean()),
                     "share": float(e.mean() ** 2 / total)})
    return sorted((r for r in rows if r["share"] >= LEAST_SHARE), key=lambda r: -r["share"])


def worst_regime(err: EquationError) -> tuple[str, float] | None:
    """The regime where the error's RMS is largest relative to its RMS overall."""
    best = None
    for name, mask in err.regime.items():
        if mask.sum() < 10:
            continue
        ratio = float(np.sqrt(np.mean(err.error[mask] ** 2))) / max(err.rms, 1e-300)
        if best is None or ratio > best[1]:
            best = (name, ratio)
    return best


def locate(data: Prepared, twin: Prepared, params: ModelParams,
           stroke: float) -> tuple[dict, dict[str, EquationError]]:
    """Where the model's equations leave a gap beyond noise that no recalibration explains,
    and what shape it has: each equation's error less its calibration-shaped part, against the
    same on the noise twin. Returns the findings (JSON) and those remainders by equation."""
    errors = {e.equation: e for e in equation_errors(data, params, stroke)}
    noise = {e.equation: without_calibration(e).rms
             for e in equation_errors(twin, params, stroke)}
    out: dict = {"equations": {}, "beyond_noise": BEYOND_NOISE}
    remainders = {}
    for name, full in errors.items():
        e = without_calibration(full)
        e.noise_rms = noise.get(name, 0.0)
        remainders[name] = e
        reg = worst_regime(e)
        out["equations"][name] = {
            "unit": e.unit, "rms": full.rms, "rms_beyond_calibration": e.rms,
            "noise_rms": e.noise_rms, "over_noise": e.over_noise,
            "terms": sparse_terms(e) if e.over_noise >= BEYOND_NOISE else [],
            "worst_regime": {"regime": reg[0], "rms_over_overall": reg[1]} if reg else None}
    ranked = sorted(out["equations"].items(), key=lambda kv: -kv[1]["over_noise"])
    top = ranked[0] if ranked and ranked[0][1]["over_noise"] >= BEYOND_NOISE else None
    if top is not None:
        eq, info = top
        sub = info["terms"][0]["subsystem"] if info["terms"] else _SUBSYSTEM_OF_EQUATION[eq]
        out["missing"] = {"equation": eq, "subsystem": sub, "terms": info["terms"],
                          "regime": info["worst_regime"]}
    else:
        out["missing"] = None
    return out, remainders


def describe(located: dict) -> str:
    """The missing physics in words, from :func:`locate`."""
    m = located.get("missing")
    if not m:
        return "no equation of the model holds an error beyond noise"
    words = f"the {m['equation']} ({m['subsystem']})"
    if m["terms"]:
        shapes = "; ".join(f"{t['meaning']} ({100 * t['share']:.0f} % of its variance)"
                           for t in m["terms"][:2])
        words += f" leaves an error shaped as {shapes}"
    else:
        words += " leaves an error no library term describes"
    if m["regime"] and m["regime"]["rms_over_overall"] > 1.3:
        words += (f", largest when {m['regime']['regime'].replace('_', ' ')} "
                  f"({m['regime']['rms_over_overall']:.1f} x its RMS overall)")
    return words

