"""How far a model's predictions are from the measurements: the gap metric of the diagnosis.

Residuals (prediction minus measurement) of each signal are divided by the signal's scale (its
spread over the dataset, at least 1 mm or 0.1 bar), squared and averaged over the scored samples:
a normalised mean square error per signal. Part of it is sensor noise no model can explain; the
*excess* subtracts it: the error a perfect model would show on data like these (see
:mod:`noise_floor`), or else the noise variance estimated from the data. The gap is

    gap = 100 % * sqrt(mean over signals of the excess)

the RMS prediction error beyond noise, in percent of the signals' spread ("excess NRMSE"), over
short-horizon predictions (see :mod:`prediction`). Signals are weighted equally, whatever their
number of samples.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from jetpipe_ros.diagnosis.data import SIGNALS, Prepared, Record
from jetpipe_ros.diagnosis.prediction import HORIZON, Prediction, predict
from jetpipe_ros.model import ModelParams

METRIC = "excess_nrmse_pct"


@dataclass
class Score:
    """Normalised mean square error per signal, and the noise part of it."""

    mse: dict[str, float]
    noise: dict[str, float]
    count: dict[str, int]

    def excess(self, signal: str) -> float:
        """Normalised MSE beyond noise of one signal (>= 0)."""
        return max(self.mse[signal] - self.noise[signal], 0.0)

    @property
    def total(self) -> float:
        """Mean normalised MSE over the scored signals."""
        return float(np.mean([self.mse[s] for s in self.mse])) if self.mse else 0.0

    @property
    def noise_total(self) -> float:
        """Mean normalised noise variance over the scored signals."""
        return float(np.mean([self.noise[s] for s in self.mse])) if self.mse else 0.0

    @property
    def gap(self) -> float:
        """The gap metric [%]: RMS excess error over the signals."""
        if not self.mse:
            return 0.0
        return 100.0 * float(np.sqrt(np.mean([self.excess(s) for s in self.mse])))

    def signal_gap(self, signal: str) -> float:
        """The gap metric [%] of one signal."""
        return 100.0 * float(np.sqrt(self.excess(signal)))

    def to_json(self) -> dict:
        """Per-signal gap [%] and the total."""
        return {"gap": self.gap, **{s: self.signal_gap(s) for s in self.mse}}


def difference_gap(differences: Iterable[tuple[str, np.ndarray]],
                   scale: Mapping[str, float]) -> float:
    """The gap metric [%] between two noise-free responses (nothing to remove for noise): the
    RMS over signals of each signal's mean square difference over its scale. ``differences``
    are (signal, differences [m or Pa]) pairs, several per signal (one per experiment)."""
    sums: dict[str, float] = {}
    counts: dict[str, int] = {}
    for s, d in differences:
        sums[s] = sums.get(s, 0.0) + float(np.sum(d ** 2))
        counts[s] = counts.get(s, 0) + d.size
    per_signal = [sums[s] / counts[s] / scale[s] ** 2 for s in sums if counts[s]]
    return 100.0 * float(np.sqrt(np.mean(per_signal))) if per_signal else 0.0


def effective_samples(s: Score, dt: float) -> float:
    """Independent pieces of evidence in a score: one per signal and prediction window."""
    return max(sum(s.count.values()) * dt / HORIZON, 1.0)


def predict_all(params: ModelParams, prepared: Prepared, role: str | None,
                mode: str = "full") -> list[Prediction | None]:
    """Predictions of the records having ``role`` samples (all records for None), else None."""
    return [predict(params, r, prepared.dt, mode, scale=prepared.scale)
            if role is None or getattr(r, role).any() else None for r in prepared.records]


def _mask(rec: Record, pred: Prediction, role: str | None,
          extra: np.ndarray | None) -> np.ndarray:
    mask = pred.free.copy()
    if role is not None:
        mask &= getattr(rec, role)
    if extra is not None:
        mask &= extra
    return mask


def score(prepared: Prepared, preds: Sequence[Prediction | None], role: str | None,
          signals: Sequence[str] = SIGNALS,
          masks: Sequence[np.ndarray | None] | None = None) -> Score:
    """Score predictions over the ``role`` samples (all for None), optionally within ``masks``."""
    sums = {s: 0.0 for s in signals}
    counts = {s: 0 for s in signals}
    for i, (rec, pred) in enumerate(zip(prepared.records, preds)):
        if pred is None:
            continue
        mask = _mask(rec, pred, role, masks[i] if masks is not None else None)
        if not mask.any():
            continue
        for s in signals:
            if s not in rec.signals():
                continue
            r = (pred.signal(s)[mask] - rec.signal(s)[mask]) / prepared.scale[s]
            sums[s] += float(r @ r)
            counts[s] += int(mask.sum())
    present = [s for s in signals if counts[s] > 0]
    return Score(mse={s: sums[s] / counts[s] for s in present},
                 noise={s: prepared.floor.get(s, (prepared.noise[s] / prepared.scale[s]) ** 2)
                        for s in present},
                 count={s: counts[s] for s in present})


def residual_vector(prepared: Prepared, preds: Sequence[Prediction | None], role: str | None,
                    stride: int = 4) -> np.ndarray:
    """Normalised residuals of the ``role`` samples (all for None; every ``stride``-th), each
    signal weighted by 1/sqrt(its sample count) so that its sum of squares is the mean of the
    per-signal MSEs."""
    parts: dict[str, list[np.ndarray]] = {s: [] for s in SIGNALS}
    for rec, pred in zip(prepared.records, preds):
        if pred is None:
            continue
        mask = _mask(rec, pred, role, None)
        idx = np.flatnonzero(mask)[::stride]
        for s in rec.signals():
            parts[s].append((pred.signal(s)[idx] - rec.signal(s)[idx]) / prepared.scale[s])
    out = []
    present = [s for s in SIGNALS if parts[s]]
    for s in present:
        r = np.concatenate(parts[s])
        if r.size:
            out.append(r / np.sqrt(r.size * len(present)))
    return np.concatenate(out) if out else np.zeros(1)


def window_errors(prepared: Prepared, preds: Sequence[Prediction | None], role: str,
                  horizon: float = HORIZON) -> np.ndarray:
    """Normalised mean square error of each ``horizon``-long window of the ``role`` samples
    (signals averaged), in a fixed order: paired samples for comparing two models.
    """
    period = max(int(round(horizon / prepared.dt)), 1)
    out = []
    for rec, pred in zip(prepared.records, preds):
        if pred is None:
            continue
        mask = _mask(rec, pred, role, None)
        for start in range(0, rec.t.size, period):
            m = mask[start:start + period]
            if m.sum() < 10:
                continue
            errs = [np.mean(((pred.signal(s)[start:start + period] -
                              rec.signal(s)[start:start + period]) / prepared.scale[s])[m] ** 2)
                    for s in rec.signals()]
            out.append(float(np.mean(errs)))
    return np.array(out)
