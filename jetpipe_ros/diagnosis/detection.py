"""How small an effect these records would still show: the detection limits of an answer of no
effect.

A verdict of ``none`` says that no candidate explains the gap beyond noise; what it is worth
depends on how large an effect could have passed unnoticed. For each candidate this module finds
the smallest size at which what the effect shows that no recalibration can imitate reaches the
noise bar: the gap [%] the calibration knobs' best linear imitation leaves of its signature
(:class:`collinearity.Imitator`, on the recalibrated model) equals :data:`verdict.NOISE_GAP`.
From that size on the effect stands out beyond noise after any recalibration the knobs allow,
so a ``none`` on these records speaks against it. It is a bound from above, not the
diagnosis' own threshold: the verdict's tests on windows of the records find smaller effects
(on the small campaign of the tests, both pressures logged, seed 3: limit 1.27 ms for a valve
delay; a 2.5 ms delay was named at 2.49 ms, and a 0.6 ms one at 0.59 ms as well).

Sizes run along one line per candidate, from where the effect vanishes to its typical size and
beyond (:func:`sized`): each knob of the typical size moves from the value at which the effect
vanishes (:attr:`candidates.Knob.off`) towards its typical value, linearly, or geometrically for
a knob searched on a log scale (a corner frequency from 300 Hz, invisible, through 30 Hz at
size 1); a knob that spans a form's shape (:attr:`candidates.Knob.extent`) keeps its typical
value. The limit is found by Brent's method on the size's logarithm (to 5 %, the knobs'
values are then good to about 2 digits), bracketed by steps of four from the typical size, up
to the end of the candidate's search range: a candidate not shown even there has no limit
within the range the diagnosis searches, and one still shown at a thousandth of its typical size
has none either (its knobs, as the candidate defines them, do not make it vanish on these
records: a port's restriction at its typical conductance with almost no volume; wall heat
exchange at the conductance meant to be invisible, 0.56 % on the small campaign of the tests).

It is the linear check of :mod:`collinearity` taken along each candidate's size, not a fit:
near its limit a real effect may be imitated a little better by the nonlinear recalibration than
by the linear one, so an effect just above the limit is likely named, not certain to be.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from scipy.optimize import brentq

from jetpipe_ros.diagnosis.candidates import Candidate, Knob
from jetpipe_ros.diagnosis.collinearity import Imitator
from jetpipe_ros.diagnosis.verdict import NOISE_GAP

#: Step [factor] of the sizes tried from the typical one until the leftover crosses the bar.
STEP = 4.0
#: Smallest size [multiple of the typical] searched.
SMALLEST = 1e-3
#: Tolerance [natural log of the size] of the limit.
TOLERANCE = 0.05


#: Why a candidate has no limit: not shown even at the end of its search range.
NOT_SHOWN = "not shown within its search range"


def _scaled(cand: Candidate) -> list[tuple[Knob, float]]:
    """The knobs of ``cand`` that move along its size, with their typical values: those of its
    typical size that do not set a form's shape and whose typical value is not where the
    effect vanishes."""
    return [(knob, cand.typical[knob.name]) for knob in cand.knobs
            if knob.name in cand.typical and not knob.extent
            and cand.typical[knob.name] != knob.off]


def sized(cand: Candidate, size: float) -> dict[str, float]:
    """The knobs of ``cand`` at ``size`` times its typical size (0: the effect vanishes, 1:
    typical); see the module's docstring."""
    out = dict(cand.typical)
    for knob, typical in _scaled(cand):
        if knob.log:
            out[knob.name] = knob.off * (typical / knob.off) ** size
        else:
            out[knob.name] = knob.off + size * (typical - knob.off)
    return out


def largest_size(cand: Candidate) -> float:
    """The size [multiple of the typical] at which the first of ``cand``'s knobs along the line
    of :func:`sized` reaches the end of its search range."""
    ends = []
    for knob, typical in _scaled(cand):
        end = knob.high if typical > knob.off else knob.low
        if knob.log:
            ends.append(math.log(end / knob.off) / math.log(typical / knob.off))
        else:
            ends.append((end - knob.off) / (typical - knob.off))
    return min(ends, default=1.0)


def detection_limit(imitator: Imitator, cand: Candidate) -> dict:
    """The smallest size of ``cand`` these records would show beyond what a recalibration
    imitates: ``times_typical`` [multiple of the typical size] and the knobs' ``values`` there;
    ``times_typical`` null and a ``note`` when there is no such size: not shown even at the end
    of its search range (``values`` there), or shown at every size searched (``values`` at the
    smallest: its knobs then do not make it vanish on these records)."""
    def excess(log_size: float) -> float:
        return imitator.imitate(cand, sized(cand, math.exp(log_size)))[1] - NOISE_GAP

    top, bottom = math.log(largest_size(cand)), math.log(SMALLEST)
    x, fx = 0.0, excess(0.0)
    step = math.log(STEP) if fx < 0.0 else -math.log(STEP)
    while True:
        y = min(max(x + step, bottom), top)
        if y == x:  # at the end of the range or of the search: no crossing
            note = (f"shown at every size down to {SMALLEST:g} of its typical" if fx >= 0.0
                    else NOT_SHOWN)
            return {"times_typical": None, "values": sized(cand, math.exp(x)), "note": note}
        fy = excess(y)
        if (fy >= 0.0) != (fx >= 0.0):
            break
        x, fx = y, fy
    size = math.exp(brentq(excess, min(x, y), max(x, y), xtol=TOLERANCE))
    return {"times_typical": size, "values": sized(cand, size), "note": None}


def detection_limits(imitator: Imitator, candidates: Sequence[Candidate]) -> dict[str, dict]:
    """:func:`detection_limit` of each of ``candidates``, by name."""
    return {cand.name: detection_limit(imitator, cand) for cand in candidates}


def unseen(limits: Mapping[str, Mapping]) -> list[str]:
    """The candidates of :func:`detection_limits` not shown at any size within their search
    range: an answer of no effect says nothing of them."""
    return [c for c, r in limits.items() if r["note"] == NOT_SHOWN]


def limit_words(limits: Mapping[str, Mapping]) -> list[str]:
    """Words for :func:`detection_limits`: the candidates that would show from a size, as
    multiples of their typical size, and those these records would not show at any size within
    their search range."""
    shown = {c: r["times_typical"] for c, r in limits.items() if r["times_typical"] is not None}
    words = []
    if shown:
        words.append("smallest size shown, times the typical (from it on the effect stands "
                     "out beyond noise after any recalibration): "
                     + ", ".join(f"{c} {x:.2g}" for c, x in shown.items()))
    hidden = unseen(limits)
    if hidden:
        words.append(f"not shown at any size within its search range: {', '.join(hidden)}")
    return words
