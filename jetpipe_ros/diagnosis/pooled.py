"""Candidates the training records favour and the held-out ones cannot confirm: what all the
records say together.

The verdict judges every candidate on held-out experiments it was not fitted on. When no
candidate explains the held-out gap, one may still fit the training records far better than the
recalibration does while predicting the held-out records no better. Two things do that. A
candidate can fit what only the training records hold, and the held-out ones rightly reject it.
Or its held-out predictions rest on what the training records leave free: an effect whose size
they pin only over the range they reach. The held-out split cannot tell these apart; all the
records together can. So the recalibration, and each such candidate jointly with it, are fitted
again on every record, training and held-out (:func:`whole`), and the candidate is *favoured by
the records as a whole* when there it removes at least :data:`verdict.MIN_SHRINKAGE` of what
the recalibration leaves, significantly, by the verdict's own tests (:func:`verdict.rank`).

That comparison is in-sample: every knob is fitted on the data it is judged on, so it names no
effect. It puts the candidate among what the answer cannot rule out, with the held-out record
whose information the training records lack (the one where the candidate's fit on the training
records falls furthest short of its fit on all of them): a training record like that decides it.

Found on a position-only record of a drooping supply (development seed 8951, case 10, the
independent plant): the recalibration leaves 0.26 % of the training records and 0.49 % held out,
within noise, so the answer is `none`; the supply line jointly with it leaves 0.10 % of the
training records but 0.46 % held out, 0.73 % on the 3 V square wave that runs the valve near
full flow, which no training record does without pressure sensors (the locked tests' full flow
shows in pressures only). Fitted on every record the line leaves 0.07 % where the recalibration
leaves 0.28 %, 0.12 % on that square wave, at a set pressure within 2 % of the plant's
regulator. Two more descents on the training records, from the size the line takes alone with
the knobs at nominal or recalibrated, ended at lower training costs than the diagnosis's own
(N log C + P: -272.8 and -270.9 against -259.1) and left 1.25 % and 0.20 % held out, while the
fit on every record scores -270.1 on the training records: they do not decide what the line
predicts at full flow.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

from jetpipe_ros.diagnosis.candidates import effect_of
from jetpipe_ros.diagnosis.data import Prepared
from jetpipe_ros.diagnosis.fit import Fit
from jetpipe_ros.diagnosis.jobs import Fitter, Job
from jetpipe_ros.diagnosis.score import Score, predict_all, score, window_errors
from jetpipe_ros.diagnosis.verdict import MIN_SHRINKAGE, MIN_T, Ranked, paired_t, rank
from jetpipe_ros.model import ModelParams

#: How the words for the favoured candidates begin in the verdict's reason (:func:`words`).
FAVOURED = "the records as a whole favour "
#: Most candidates refitted on all records, those the training records favour most first: each
#: costs a joint fit.
MOST = 2


def whole(prepared: Prepared) -> Prepared:
    """The same data with every compared sample both training and held-out: a fit on it uses
    every record, and its "held-out" scores are over every record too. The noise floor (of the
    held-out windows) and the nuisance directions (already fitted on all records) are not
    carried over."""
    records = [dataclasses.replace(r, train=r.train | r.holdout, holdout=r.train | r.holdout)
               for r in prepared.records]
    return dataclasses.replace(prepared, records=records, floor={}, floor_windows=None,
                               nuisance=None, split_note=f"every record ({prepared.split_note})")


def suspects(prepared: Prepared, cal: Fit, ranking: Sequence[Ranked]) -> list[Ranked]:
    """The single candidates (fitted jointly with the calibration) that do not explain the
    held-out gap but fit the training records better than the recalibration ``cal`` by the
    verdict's measure (:attr:`verdict.Ranked.explains`, on the training records): at least
    :data:`MIN_SHRINKAGE` of its training gap removed, and significantly: the error removed
    larger than the noise's, or a paired t over the training windows of at least
    :data:`MIN_T`. At most :data:`MOST`, the largest training shrinkage first."""
    base = None
    found = []
    for r in ranking:
        f = r.fit
        if len(f.effects) != 1 or not f.calibrated or r.explains or cal.train.gap <= 0.0:
            continue
        shrink = 1.0 - f.train.gap / cal.train.gap
        if shrink < MIN_SHRINKAGE:
            continue
        removed = (cal.train.total - f.train.total) / max(cal.train.noise_total, 1e-300)
        if removed < 1.0:
            if base is None:
                base = window_errors(prepared, predict_all(cal.params, prepared, "train"),
                                     "train")
            windows = window_errors(prepared, predict_all(f.params, prepared, "train"),
                                    "train")
            if paired_t(base, windows) < MIN_T:
                continue
        found.append((shrink, r))
    found.sort(key=lambda item: -item[0])
    return [r for _, r in found[:MOST]]


def check(fitter: Fitter, nominal: ModelParams, cal: Fit, rows: Sequence[Ranked],
          budgets: tuple[int, int], progress: Callable[[str], None]) -> list[dict]:
    """Fit the recalibration ``cal`` and each candidate of ``rows`` (:func:`suspects`) on every
    record, from where they ended on the training records (``budgets``: the calibration's and a
    joint fit's), and compare them there; one row of ``visibility.favoured_by_all_records`` per
    candidate."""
    if not rows:
        return []
    progress(f"{', '.join(r.fit.name for r in rows)}: fit the training records better than "
             f"the recalibration, not the held-out ones; fitting "
             f"{'them' if len(rows) > 1 else 'it'} and the recalibration on every record")
    cal_budget, joint_budget = budgets
    fits = fitter.run([Job(nominal, cal.groups, cal.z, cal_budget, pooled=True)]
                      + [Job(nominal, r.fit.groups, r.fit.z, joint_budget, pooled=True)
                         for r in rows],
                      [f"{g} on every record" for g in ("calibration",
                                                        *(r.fit.name for r in rows))])
    base, pooled = fits[0], fits[1:]
    recalibrated = per_record(fitter.prepared, {"recalibration": cal,
                                                "recalibration_pooled": base})
    out = []
    for r, p in zip(rows, pooled):
        (together,) = rank([p], base.holdout, base.holdout_windows, fitter.prepared.dt)
        scores = per_record(fitter.prepared, {"trained": r.fit, "pooled": p})
        scores = {name: {**recalibrated[name], **by} for name, by in scores.items()}
        out.append({
            "candidate": r.fit.name, "effect": effect_of(r.fit.name),
            "train_gap": r.fit.train.gap, "holdout_gap": r.fit.holdout.gap,
            "recalibration_train_gap": cal.train.gap,
            "recalibration_holdout_gap": cal.holdout.gap,
            "pooled_gap": p.holdout.gap, "recalibration_pooled_gap": base.holdout.gap,
            "pooled_shrinkage": together.shrinkage, "pooled_t": together.t,
            "favoured": together.explains,
            "params": p.values[r.fit.name],
            "decisive_record": decisive(scores),
            "by_record": [{"record": name, **{k: v.gap for k, v in by.items()}}
                          for name, by in scores.items()]})
    return out


def per_record(prepared: Prepared, fits: dict[str, Fit]) -> dict[str, dict[str, Score]]:
    """Each held-out record's score under each of ``fits`` (by a name of the caller's)."""
    out: dict[str, dict[str, Score]] = {}
    for name, fit_ in fits.items():
        preds = predict_all(fit_.params, prepared, "holdout")
        for i, (rec, pred) in enumerate(zip(prepared.records, preds)):
            if pred is None:
                continue
            s = score(prepared, [p if j == i else None for j, p in enumerate(preds)], "holdout")
            if s.count:
                out.setdefault(rec.name, {})[name] = s
    return out


def decisive(scores: dict[str, dict[str, Score]]) -> str:
    """The held-out record on which the candidate fitted on the training records (``trained``)
    falls furthest short of its fit on every record (``pooled``), by :func:`per_record`'s
    ``scores``: the one whose information the training records lack."""
    return max(scores, key=lambda r: scores[r]["trained"].total - scores[r]["pooled"].total)


def words(rows: Sequence[dict]) -> str:
    """The favoured candidates in words, for the verdict's reason."""
    each = []
    for row in rows:
        if not row["favoured"]:
            continue
        each.append(
            f"{row['candidate']} (fitted on every record, training and held-out, it leaves "
            f"{row['pooled_gap']:.2f} % where the recalibration leaves "
            f"{row['recalibration_pooled_gap']:.2f} %; fitted on the training records it "
            f"leaves {row['train_gap']:.2f} % of them against the recalibration's "
            f"{row['recalibration_train_gap']:.2f} %, but {row['holdout_gap']:.2f} % held out "
            f"against {row['recalibration_holdout_gap']:.2f} %: a training record like "
            f"'{row['decisive_record']}' would decide it)")
    if not each:
        return ""
    return (FAVOURED + "; and ".join(each)
            + ": what it predicts on the held-out records rests on what the training records "
            "leave free, so the held-out ones cannot confirm it, nor this answer rule it out")
