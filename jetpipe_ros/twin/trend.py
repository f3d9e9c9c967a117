"""``jetpipe trend``: an actuator's diagnoses over time, and the drifts among them.

Each diagnosis (a ``diagnosis.json`` in one of the folders given, or below it) is one point in
time. Its date is, in this order: a ``date`` field (ISO 8601) in ``diagnosis.json``; a date in
the name of the folder holding it or of one above it (``2026-03-01``, ``20260301`` or
``20260301T120000Z``, as the monitor names its captures); else the time ``diagnosis.json`` was
last modified. The series followed are the calibration knobs (each a factor on the nominal
model) and the parameters of the effect each diagnosis names (``effect.parameter``, missing at
dates whose verdict is another effect).

A **drift** is a steady change: the least-squares line through a series against time
(:func:`scipy.stats.linregress`) whose slope is at least :data:`MIN_T` times its standard error
(the diagnosis' own bar of significance), with at least :data:`MIN_POINTS` dates. Its rate is
the slope per day, stated with that standard error: seals wearing show as a friction knob
rising, a growing leak as its coefficient rising.
"""

from __future__ import annotations

import io
import json
import math
import re
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from scipy import stats

from jetpipe_ros.diagnosis.verdict import MIN_T
from jetpipe_ros.figures import pyplot
from jetpipe_ros.fileio import FileError

#: Fewest dates for a slope to be judged (a line through two points has no scatter).
MIN_POINTS = 3
DAY = 86400.0
_NAME_DATE = re.compile(r"(\d{4})-?(\d{2})-?(\d{2})(?:T(\d{2})(\d{2})(\d{2})Z?)?")


class TrendError(FileError):
    """A diagnosis cannot be read; the message names the file."""


@dataclass
class Point:
    """One diagnosis: when, where, and the values followed."""

    date: datetime
    source: str  #: how the date was found: field, name or mtime
    path: Path  #: the diagnosis.json
    effect: str
    values: dict[str, float]


@dataclass
class Series:
    """One quantity over time and its fitted line."""

    name: str
    days: np.ndarray  #: days since the first diagnosis
    values: np.ndarray
    slope: float = math.nan  #: rate [unit per day]
    stderr: float = math.nan  #: standard error of the rate [unit per day]
    intercept: float = math.nan

    @property
    def t(self) -> float:
        """Slope over its standard error (0 when not judged)."""
        if not math.isfinite(self.slope) or not math.isfinite(self.stderr):
            return 0.0
        if self.stderr == 0.0:
            return 0.0 if self.slope == 0.0 else math.copysign(math.inf, self.slope)
        return self.slope / self.stderr

    @property
    def drift(self) -> bool:
        """A steady change: enough dates and a slope at least MIN_T standard errors off 0."""
        return self.days.size >= MIN_POINTS and abs(self.t) >= MIN_T

    def to_json(self) -> dict:
        return {"name": self.name, "points": int(self.days.size),
                "first": float(self.values[0]), "last": float(self.values[-1]),
                "rate_per_day": self.slope, "rate_stderr_per_day": self.stderr,
                "t": self.t, "drift": self.drift}


def _date(doc: dict, path: Path) -> tuple[datetime, str]:
    if isinstance(doc.get("date"), str):
        try:
            d = datetime.fromisoformat(doc["date"].replace("Z", "+00:00"))
            return (d if d.tzinfo else d.replace(tzinfo=timezone.utc)), "field"
        except ValueError as exc:
            raise TrendError(f"{path}: field date {doc['date']!r} is not an ISO 8601 "
                             f"date") from exc
    for part in reversed(path.parent.parts):
        m = _NAME_DATE.search(part)
        if m:
            y, mo, d, hh, mm, ss = (int(g) if g else 0 for g in m.groups())
            try:
                return datetime(y, mo, d, hh, mm, ss, tzinfo=timezone.utc), "name"
            except ValueError:
                continue
    return datetime.fromtimestamp(path.stat().st_mtime, tz=timezone.utc), "mtime"


def read_point(path: Path) -> Point:
    """One diagnosis.json as a :class:`Point`; TrendError naming the file if unreadable."""
    try:
        doc = json.loads(path.read_text())
        knobs = doc["calibration"]["knobs"]
        verdict = doc["verdict"]
    except OSError as exc:
        raise TrendError(f"{path}: cannot read: {exc.strerror}") from exc
    except (ValueError, KeyError, TypeError) as exc:
        raise TrendError(f"{path}: not a diagnosis (diagnosis.json with calibration.knobs "
                         f"and verdict): {exc!r}") from exc
    date, source = _date(doc, path)
    values = {k: float(v) for k, v in knobs.items() if isinstance(v, (int, float))}
    effect = str(verdict.get("effect", "none"))
    for k, v in (verdict.get("params") or {}).items():
        if isinstance(v, (int, float)):
            values[f"{effect}.{k}"] = float(v)
    return Point(date, source, path, effect, values)


def find_diagnoses(dirs: list[str]) -> list[Path]:
    """Every diagnosis.json in or below the folders ``dirs``; TrendError for a folder that
    holds none."""
    found = []
    for d in dirs:
        root = Path(d)
        if not root.is_dir():
            raise TrendError(f"{root}: no such directory")
        hits = sorted(root.rglob("diagnosis.json"))
        if not hits:
            raise TrendError(f"{root}: no diagnosis.json in it or below it")
        found += hits
    return sorted(set(found))


def trend(points: list[Point]) -> list[Series]:
    """Every quantity over the points (sorted by date), each with its fitted line."""
    points = sorted(points, key=lambda p: p.date)
    t0 = points[0].date
    names = sorted({k for p in points for k in p.values})
    out = []
    for name in names:
        have = [p for p in points if name in p.values]
        days = np.array([(p.date - t0).total_seconds() / DAY for p in have])
        values = np.array([p.values[name] for p in have])
        s = Series(name, days, values)
        if days.size >= MIN_POINTS and np.ptp(days) > 0.0:
            fit = stats.linregress(days, values)
            s.slope, s.stderr, s.intercept = (float(fit.slope), float(fit.stderr),
                                              float(fit.intercept))
        out.append(s)
    return out


def table(series: list[Series]) -> str:
    """The series as a text table, drifts marked."""
    lines = [f"{'quantity':34s} {'dates':>5s} {'first':>10s} {'last':>10s} "
             f"{'rate per day':>24s} {'t':>7s}  drift"]
    for s in series:
        rate = (f"{s.slope:+.4g} +- {s.stderr:.2g}" if math.isfinite(s.slope) else "-")
        lines.append(f"{s.name:34s} {s.days.size:5d} {s.values[0]:10.4g} {s.values[-1]:10.4g} "
                     f"{rate:>24s} {s.t:7.1f}  {'DRIFT' if s.drift else ''}")
    return "\n".join(lines)


def plot(series: list[Series], t0: datetime) -> bytes:
    """PNG of every series against days since ``t0``, drifts in red with their line."""
    plt = pyplot()

    cols = 3
    rows = max(math.ceil(len(series) / cols), 1)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.6 * rows), squeeze=False)
    for ax, s in zip(axes.flat, series):
        color = "tab:red" if s.drift else "tab:blue"
        ax.plot(s.days, s.values, "o", color=color)
        if math.isfinite(s.slope):
            x = np.array([s.days.min(), s.days.max()])
            ax.plot(x, s.intercept + s.slope * x, "-", color=color, lw=1)
        title = s.name + (f"\ndrift {s.slope:+.3g} +- {s.stderr:.2g} /day" if s.drift else "")
        ax.set_title(title, fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(series):]:
        ax.axis("off")
    fig.supxlabel(f"days since {t0:%Y-%m-%d %H:%M} UTC", fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()
