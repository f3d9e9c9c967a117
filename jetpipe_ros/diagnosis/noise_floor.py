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

from jetpipe_ros.diagnosis.data import Prepared, smoothed, velocity
from jetpipe_ros.diagnosis.score import predict_all, score, window_errors
from jetpipe_ros.model import ModelParams, simulate

SEED = 20261122


def twin(prepared: Prepared, params: ModelParams, seed: int = SEED) -> Prepared:
    """The dataset re-measured on the model ``params`` with the estimated sensor noise."""
    rng = np.random.default_rng(seed)
    records = []
    for rec in prepared.records:
        p = params.with_values({
            "mechanics.locked": rec.locked, "sensors.noise": False,
            "integration.sample_time": prepared.dt,
            "mechanics.initial_position": float(np.clip(rec.smooth["y"][0], -0.5, 0.5)),
            "chamber.initial_pressure_1": float(np.clip(rec.smooth["p1"][0], 1e4, 1.2e6)),
            "chamber.initial_pressure_2": float(np.clip(rec.smooth["p2"][0], 1e4, 1.2e6)),
            "chamber.regulated": rec.regulated})
        tr = simulate(p, rec.u, rec.f_load)
        y = tr.y + prepared.noise["y"] * rng.standard_normal(tr.y.size)
        p1 = tr.p1 + prepared.noise["p1"] * rng.standard_normal(tr.y.size)
        p2 = tr.p2 + prepared.noise["p2"] * rng.standard_normal(tr.y.size)
        dt = prepared.dt
        records.append(dataclasses.replace(
            rec, y=y, p1=p1, p2=p2, v=np.zeros_like(y) if rec.locked else velocity(y, dt),
            smooth={"y": smoothed(y, dt), "p1": smoothed(p1, dt), "p2": smoothed(p2, dt)}))
    return dataclasses.replace(prepared, records=records, floor={})


def calibrate(prepared: Prepared, params: ModelParams) -> tuple[dict[str, float], np.ndarray]:
    """Per-signal normalised mean square error of the perfect model on the held-out twin, and
    its error per held-out prediction window (:func:`score.window_errors`, aligned with the
    data's windows): what noise alone leaves in each window."""
    tw = twin(prepared, params)
    preds = predict_all(params, tw, "holdout")
    return dict(score(tw, preds, "holdout").mse), window_errors(tw, preds, "holdout")
