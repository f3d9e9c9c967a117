"""Which way the signals count: a rig's or a logger's sign conventions, measured.

The data contract counts the command so that +u charges chamber 1 (p1 rises, p2 falls) and
drives the piston towards +y. A position sensor mounted the other way round, a valve wired the
other way, or the two chamber pressures logged under each other's names break that, and a model
compared with such a record misses by the signals' whole spread: on a nominal actuator's
campaign logged with its position counted the other way, the held-out gap was 92 % of the
spread and the recalibration moved nine knobs by 8-150 % trying to follow. Nothing in the
physics does this; it is a convention, like the time base (:mod:`alignment`), and it is read
before anything is fitted (the time base's own fit needs the signs right).

**What is measured.** The nominal model predicts every record as the diagnosis predicts it
(restarted from the measurements every second, :mod:`prediction`), and for each measured signal
the changes over :data:`CHANGE_S` of the prediction are correlated with the measured ones, in
each record (for the position, the free-piston ones), the records' correlations combined by
Fisher's z (:func:`correlations`). A model whose parameters are off, or that misses an effect,
still moves each signal the way the measurement moves: on the self-check's plants the lowest
correlation was 0.94 (nine development records, parameters off and one effect each, every
sensor set), 0.81 (the twelve clean records of seed 1847) and 0.82 (those of held-out seed
6911), on the paper's identification records (a friction rig's tests among them) 0.97, and on
the record of hardware outside the model class (an on/off valve, ``test/foreign_hardware.py``)
0.44. A signal counted the other way moves against its prediction (-0.59 to -0.86 on the
same records rewritten so, the paper's position -0.13: the restarts carry the wrong sign into
the other signals, so it is not -1).

**What is decided.** When no signal is anti-correlated beyond :data:`Z_SIGN` standard errors,
the record is read as logged, and nothing else is computed. Otherwise each other reading the
sensors allow (the command reversed, the position reversed, the pressures crossed, and their
combinations) is tried by rewriting the record so and predicting it again; the reading whose
worst signal correlates best is taken, if every signal then correlates beyond :data:`Z_SIGN`
standard errors, else the record is read as logged and the anti-correlation said. The standard
error is Fisher's, from the number of non-overlapping :data:`CHANGE_S` windows. Readings whose
worst correlation is within :data:`Z_SIGN` standard errors of the best's fit as well, and are
said: with the position alone a reversed position and a reversed command are the same record
for a symmetric actuator, and with both pressures a reversed command is a reversed position
with crossed pressures (the fewest changes is then taken).

The correction is made on the record as read (:func:`rewritten`); the declaration that makes
every tool read it so (``units: {y: -m}``, ``{u: -V}``, ``columns: {p1: p2, p2: p1}``,
:mod:`jetpipe_ros.dataset.units`) is said with it.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from jetpipe_ros.dataset import Dataset
from jetpipe_ros.diagnosis.data import SIGNALS, Prepared, prepare
from jetpipe_ros.diagnosis.score import predict_all
from jetpipe_ros.model import ModelParams

#: Span of the changes compared [s]: long against the sensors' noise and a few samples of time
#: offset, short against the restarts' 1 s.
CHANGE_S = 0.01
#: Largest correlation taken into Fisher's z (a noise-free record correlates to 1 exactly).
CLIP = 1.0 - 1e-9
#: Standard errors (Fisher's z) beyond which a correlation counts as positive or negative.
Z_SIGN = 5.0
#: The changes a reading makes to a record, in the order they are said.
CHANGES = ("u", "y", "p")
#: Each change in words, and the declaration that makes the reader do it.
WORDS = {"u": "the command counted the other way round (a valve wired the other way)",
         "y": "the position counted the other way round (a sensor mounted the other way)",
         "p": "the chamber pressures under each other's names"}
DECLARATIONS = {"u": "units: {u: -V}", "y": "units: {y: -m}",
                "p": "columns: {p1: p2, p2: p1}"}


@dataclass(frozen=True)
class Reading:
    """One reading of a record's signs: the changes it makes (a subset of :data:`CHANGES`) and
    each signal's correlation with the nominal model's prediction when read so."""

    changes: tuple[str, ...]
    correlation: dict[str, float]
    stderr: dict[str, float]  #: of each correlation (Fisher's, at its value)

    @property
    def worst(self) -> float:
        """The lowest correlation over the signals."""
        return min(self.correlation.values())

    def beyond(self, sign: float) -> list[str]:
        """The signals correlated with ``sign`` (+1 or -1) beyond :data:`Z_SIGN` standard
        errors."""
        return [s for s, r in self.correlation.items()
                if sign * r > Z_SIGN * self.stderr[s]]

    def words(self) -> str:
        """The changes in words, or ``as logged``."""
        return " and ".join(WORDS[c] for c in self.changes) or "as logged"


@dataclass(frozen=True)
class Signs:
    """What :func:`measure` found: the reading taken, the record as logged, the readings that
    fit as well, and the reading in a sentence."""

    taken: Reading
    as_logged: Reading
    also_fit: tuple[Reading, ...]
    words: str

    @property
    def against(self) -> list[str]:
        """The signals that, as logged, move against the model (:data:`Z_SIGN`)."""
        return self.as_logged.beyond(-1.0)

    @property
    def changes(self) -> tuple[str, ...]:
        """The changes to make to the record."""
        return self.taken.changes

    def to_json(self) -> dict:
        """``data.signs`` of diagnosis.json."""
        return {"changes": list(self.taken.changes),
                "correlation": self.taken.correlation,
                "as_logged_correlation": self.as_logged.correlation,
                "against_as_logged": self.against,
                "also_fit": [list(r.changes) for r in self.also_fit],
                "explanation": self.words}


def correlations(prepared: Prepared, nominal: ModelParams) -> tuple[dict, dict]:
    """Each measured signal's correlation between the measured and the nominal model's
    predicted changes over :data:`CHANGE_S`, and its standard error: each record's correlation,
    combined over the records by Fisher's z weighted by the record's windows. Records in which
    a signal moves in other regimes (a free piston's, a friction rig's) each speak for
    themselves: pooled, the sums of the ones with the largest swings outweighed the others (the
    paper's identification records with the position reversed: -0.01 pooled, their open-loop
    square wave alone -0.43, the friction rig's thirteen tests near 0, holding the predicted
    piston at the end stop the reversed position started it at)."""
    lag = max(int(round(CHANGE_S / prepared.dt)), 1)
    z = {s: [] for s in SIGNALS}
    weight = {s: [] for s in SIGNALS}
    for rec, pred in zip(prepared.records, predict_all(nominal, prepared, None)):
        for s in rec.signals():
            ok = (rec.train | rec.holdout) & pred.free
            both = ok[lag:] & ok[:-lag]
            m, p = rec.signal(s), pred.signal(s)
            dm, dp = (m[lag:] - m[:-lag])[both], (p[lag:] - p[:-lag])[both]
            windows = int(both.sum()) // lag
            mm, pp = dm @ dm, dp @ dp
            if windows > 3 and mm > 0.0 and pp > 0.0:
                r = float(np.clip(dm @ dp / math.sqrt(mm * pp), -CLIP, CLIP))
                z[s].append(math.atanh(r))
                weight[s].append(windows - 3)
    r, se = {}, {}
    for s in SIGNALS:
        if weight[s]:
            total = float(sum(weight[s]))
            r[s] = math.tanh(float(np.dot(z[s], weight[s])) / total)
            se[s] = (1.0 - r[s] ** 2) / math.sqrt(total)
    return r, se


def rewritten(dataset: Dataset, changes: Sequence[str]) -> Dataset:
    """``dataset`` with ``changes`` made to every experiment: ``u`` the command negated, ``y``
    the position (and a logged velocity) negated, ``p`` the two pressures exchanged."""
    if not changes:
        return dataset
    experiments = []
    for exp in dataset.experiments:
        out = dataclasses.replace(exp, notes=list(exp.notes))
        if "u" in changes:
            out.u = -exp.u
        if "y" in changes:
            out.y = None if exp.y is None else -exp.y
            out.v = None if exp.v is None else -exp.v
        if "p" in changes:
            out.p1, out.p2 = exp.p2, exp.p1
        experiments.append(out)
    return dataclasses.replace(dataset, experiments=experiments)


def read(dataset: Dataset, prepared: Prepared, nominal: ModelParams
         ) -> tuple[Signs, Dataset, Prepared]:
    """``dataset``'s signs measured against ``nominal`` (:func:`measure`; ``prepared``: it as
    logged), and the dataset and its preparation as the reading takes them (as logged when it
    changes nothing)."""
    signs = measure(dataset, prepared, nominal)
    if signs.changes:
        dataset = rewritten(dataset, signs.changes)
        prepared = prepare(dataset)
    return signs, dataset, prepared


def _reading(dataset: Dataset, changes: tuple[str, ...], nominal: ModelParams) -> Reading:
    r, se = correlations(prepare(rewritten(dataset, changes)), nominal)
    return Reading(changes, r, se)


def measure(dataset: Dataset, prepared: Prepared, nominal: ModelParams) -> Signs:
    """Read ``dataset``'s sign conventions (``prepared``: it as logged) against ``nominal``."""
    logged = Reading((), *correlations(prepared, nominal))
    against = logged.beyond(-1.0)
    if not against:
        return Signs(logged, logged, (), "every signal moves the way the model moves it")
    sensors = prepared.sensors
    possible = [c for c in CHANGES
                if c == "u" or (c == "y" and "y" in sensors)
                or (c == "p" and any(p in sensors for p in ("p1", "p2")))]
    readings = [_reading(dataset, combo, nominal)
                for k in range(1, len(possible) + 1)
                for combo in itertools.combinations(possible, k)]
    fitting = [x for x in readings if len(x.beyond(+1.0)) == len(x.correlation)]
    moved = ", ".join(f"{s} {logged.correlation[s]:+.2f}" for s in against)
    if not fitting:
        return Signs(logged, logged, (), (
            f"the nominal model's changes and the measured ones are anti-correlated ({moved}) "
            f"and no other reading of the signs makes every signal follow the model: read as "
            f"logged"))
    top = max(fitting, key=lambda x: x.worst)
    ties = [x for x in fitting if top.worst - x.worst <= Z_SIGN * max(top.stderr.values())]
    best = min(ties, key=lambda x: (len(x.changes), -x.worst))  # the fewest changes that fit
    also = tuple(x for x in ties if x is not best)
    said = ", ".join(f"{s} {r:+.2f}" for s, r in best.correlation.items())
    words = (f"the measured changes run against the nominal model's ({moved}); read with "
             f"{best.words()} they follow it ({said}), and are read so; "
             f"declare {', '.join(DECLARATIONS[c] for c in best.changes)} in dataset.yaml for "
             f"every tool to read them so")
    if also:
        words += ("; the records fit as well with " + " or with ".join(x.words() for x in also)
                  + ", which they cannot tell apart")
    return Signs(best, logged, also, words)
