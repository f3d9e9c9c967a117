"""What sensor noise alone explains: the error a perfect model would show on data like these.

Sensor noise enters the score twice: directly, and through the measured states every prediction
restarts from. The second part depends on the experiments, so it is measured rather than assumed:
a twin of the dataset is simulated with the model itself (same commands, pistons and split), the
estimated sensor noise is added, and the twin is scored exactly as the data are. Its per-signal
error is the floor that the gap metric subtracts; its error per prediction window is what a
model's remaining error is tested against (is a gap left beyond noise?).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jetpipe_ros.diagnosis.data import SIGNALS, Prepared, smoothed, velocity
from jetpipe_ros.diagnosis.prediction import initial_state
from jetpipe_ros.diagnosis.score import predict_all, score, window_errors
from jetpipe_ros.model import ModelParams, simulate

SEED = 20261122


def twin(prepared: Prepared, params: ModelParams, seed: int = SEED) -> Prepared:
    """The dataset re-measured on the model ``params`` with the estimated sensor noise."""
    rng = np.random.default_rng(seed)
    records = []
    dt = prepared.dt
    for rec in prepared.records:
        p = params.at_sample_time(dt).with_values({
            "mechanics.locked": rec.locked, "sensors.noise": False,
            **initial_state(params, rec.smooth["y"], rec.smooth["p1"], rec.smooth["p2"]),
            "chamber.regulated": rec.regulated})
        tr = simulate(p, rec.u, rec.f_load)
        # The twin measures what the record measured, no more, on its sensors' lattices.
        sig = {s: _logged(getattr(tr, s), prepared.noise[s], prepared.resolution.get(s, 0.0),
                          rng) if rec.measured(s) else np.full(tr.y.size, np.nan)
               for s in SIGNALS}
        y = sig["y"]
        moving = not rec.locked and rec.measured("y")
        records.append(dataclasses.replace(
            rec, **sig, v=velocity(y, dt) if moving else np.zeros_like(y),
            smooth={s: smoothed(x, dt) if rec.measured(s) else x for s, x in sig.items()}))
    return dataclasses.replace(prepared, records=records, floor={})


def _logged(x: np.ndarray, noise: float, step: float, rng: np.random.Generator) -> np.ndarray:
    """``x`` as a sensor of white noise and resolution ``step`` (0: none) logs it, ``noise``
    [its unit] the two together: the white part sqrt(noise^2 - step^2 / 12) added, then the
    value rounded to the lattice (Widrow's uniform quantisation noise, step^2 / 12)."""
    white = np.sqrt(max(noise ** 2 - step ** 2 / 12.0, 0.0))
    x = x + white * rng.standard_normal(x.size)
    return np.round(x / step) * step if step > 0.0 else x


def calibrate(prepared: Prepared, params: ModelParams) -> tuple[dict[str, float], np.ndarray]:
    """Per-signal normalised mean square error of the perfect model on the held-out twin, and
    its error per held-out prediction window (:func:`score.window_errors`, aligned with the
    data's windows): what noise alone leaves in each window."""
    tw = twin(prepared, params)
    preds = predict_all(params, tw, "holdout")
    return dict(score(tw, preds, "holdout").mse), window_errors(tw, preds, "holdout")
