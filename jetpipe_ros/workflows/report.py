"""The diagnosis report: one self-contained HTML page (figures inlined as PNG).

Top to bottom: a plain-language summary; the recalibrated parameters against nominal; the ranking
of candidates with their held-out gap;
model against data on the held-out experiment with the largest gap; the gap by regime; the
frequency response of data, nominal and augmented models; then the numbers (signals,
subsystems, the paper's metrics, what the experiments cannot show, how the data were split and
corrected, and a chart of which samples of each experiment were compared).
"""

from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np
import yaml

from jetpipe_ros.dataset import grouped_notes
from jetpipe_ros.diagnosis.calibration import NAME as CALIBRATION_GROUP
from jetpipe_ros.diagnosis.candidates import CANDIDATES
from jetpipe_ros.diagnosis.collinearity import ADDED, imitated_effects, telling
from jetpipe_ros.diagnosis.data import Prepared, Record
from jetpipe_ros.diagnosis.detection import unseen
from jetpipe_ros.diagnosis.diagnose import NOT_RULED_OUT
from jetpipe_ros.diagnosis.nuisance import words as nuisance_words
from jetpipe_ros.diagnosis.pooled import FAVOURED
from jetpipe_ros.diagnosis.separation import words as stand_in_words
from jetpipe_ros.diagnosis.verdict import NO_EFFECT
from jetpipe_ros.figures import png_img, pyplot
from jetpipe_ros.model import ModelParams
from jetpipe_ros.model.actuator import hysteresis_plays, port_time_constant

COLORS = {"data": "#444444", "nominal": "#d62728", "augmented": "#1f77b4"}


#: The ranking chart's bars: the verdict's candidate, others that explain the gap, those that
#: explain it but a rule leaves out (:func:`jetpipe_ros.diagnosis.verdict.left_out`; hatched),
#: and those that do not explain it.
RANK_COLORS = {"named": "#1f77b4", "explains": "#9ecae1", "left out": "#9ecae1", "no": "#cccccc"}


def ranking_figure(result: dict) -> str:
    """Held-out gap of each candidate on the recalibrated model (bars, best first) against the
    nominal and the recalibrated model's."""
    plt = pyplot()
    from matplotlib.patches import Patch  # after pyplot(): matplotlib is imported on first use
    rows = result["ranking"]
    names = [r["candidate"] for r in rows]
    gaps = [r["holdout_gap"] for r in rows]
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(rows) + 1.2))
    kinds = ["named" if r["candidate"] == result["verdict"]["candidate"] else
             "left out" if r.get("left_out") else "explains" if r["explains"] else "no"
             for r in rows]
    colors = [RANK_COLORS[k] for k in kinds]
    bars = ax.barh(names[::-1], gaps[::-1], color=colors[::-1])
    for bar, kind in zip(bars, kinds[::-1]):
        if kind == "left out":  # explains, but a rule leaves it out: the verdict says why
            bar.set_hatch("///")
            bar.set_edgecolor("#ffffff")
    handles = [Patch(facecolor=RANK_COLORS[kind], edgecolor="#ffffff", label=text,
                     hatch="///" if kind == "left out" else None)
               for kind, text in (("named", "named"), ("explains", "explains"),
                                  ("left out", "explains, left out by a rule"),
                                  ("no", "does not explain")) if kind in kinds]
    handles.append(ax.axvline(result["gap"]["nominal"], color=COLORS["nominal"], ls="--",
                              label=f"nominal {result['gap']['nominal']:.2f} %"))
    handles.append(ax.axvline(result["gap"]["recalibrated"], color="#888888", ls=":",
                              label=f"recalibrated {result['gap']['recalibrated']:.2f} %"))
    for i, r in enumerate(rows[::-1]):
        ax.text(r["holdout_gap"], i, f"  {100 * r['shrinkage']:.0f} %", va="center", fontsize=8)
    ax.set_xlim(0.0, 1.12 * max(gaps + [result["gap"]["nominal"], 0.01]))  # room for labels
    ax.set_xlabel("held-out gap, excess NRMSE [%] (labels: shrinkage of what recalibration "
                  "leaves)")
    # Above the bars: inside, it covered the shrinkage labels of the last ones.
    ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=3,
              fontsize=8, frameon=False)
    return png_img(fig)


def favoured_figure(row: dict) -> str:
    """Each held-out record's gap under the recalibration and under a candidate the records as
    a whole favour, each fitted on the training records and on every record
    (``visibility.favoured_by_all_records``): where the training records leave it free."""
    plt = pyplot()
    records = [r["record"] for r in row["by_record"]]
    fig, ax = plt.subplots(figsize=(8, 0.75 * len(records) + 1.4))
    y = np.arange(len(records))[::-1]
    for k, (key, label, color) in enumerate((
            ("recalibration", "recalibration, fitted on the training records", "#888888"),
            ("recalibration_pooled", "recalibration, fitted on every record", "#cccccc"),
            ("trained", f"{row['candidate']}, fitted on the training records", "#ff7f0e"),
            ("pooled", f"{row['candidate']}, fitted on every record", COLORS["augmented"]))):
        ax.barh(y + (1.5 - k) * 0.2, [r[key] for r in row["by_record"]], height=0.2,
                color=color, label=label)
    ax.set_yticks(y, [f"{r} (decisive)" if r == row["decisive_record"] else r
                      for r in records])
    ax.set_xlabel("held-out gap, excess NRMSE [%]")
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize=8, frameon=False)
    return png_img(fig)


def placement_figure(placement: dict) -> str:
    """Where the gap starts (:mod:`placement`): the share of the held-out gap each one-signal
    experiment removes, against the share that places a cause, and the gap each subsystem's
    replay with measured inputs leaves."""
    plt = pyplot()
    exps = placement["experiments"]
    labels = [f"{e['signal']} sensor: lag, gain, offset" if e["subsystem"] == "sensors" else
              "valve: null offset of the command" for e in exps]
    removed = [100 * max(e["removed"], 0.0) for e in exps]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 0.4 * len(exps) + 1.6),
                                 gridspec_kw={"width_ratios": [3, 2]})
    colors = ["#1f77b4" if r >= 100 * placement["places_at"] else "#cccccc" for r in removed]
    ax.barh(labels[::-1], removed[::-1], color=colors[::-1])
    ax.axvline(100 * placement["places_at"], color="#d62728", ls="--")
    ax.text(100 * placement["places_at"], len(exps) - 0.45, " places the cause", color="#d62728",
            fontsize=8, va="bottom")
    ax.set_xlim(0, 100)
    ax.set_xlabel("held-out gap removed by changing this alone [%]")
    replays = placement["replays"]
    names = ["valve +\nchambers\n(fed measured\nmotion)", "mechanics\n(fed measured\npressures)"]
    # A replay with nothing measured to compare (None: no pressure; the mechanics without both)
    # is not a zero gap: drawn as not judged.
    gaps = [replays[k]["gap"] if replays[k] else None for k in ("valve_and_chambers", "mechanics")]
    bx.bar(names, [g or 0.0 for g in gaps], color=["#9ecae1", "#fdae6b"])
    for i, g in enumerate(gaps):
        if g is None:
            bx.text(i, 0.0, "not judged:\ntoo few\nsensors", ha="center", va="bottom",
                    fontsize=8, color="#666666")
    bx.set_ylim(0.0, 1.2 * max([g for g in gaps if g is not None] or [0.0]) or 1.0)
    bx.set_ylabel("held-out gap of the replay [%]")
    bx.set_title(f"answer: {placement['subsystem']}", fontsize=10)
    fig.tight_layout()
    return png_img(fig)


def placement_section(placement: dict) -> str:
    """The report's section on where an unlisted gap starts, in words and a figure."""
    words = placement["words"][0].upper() + placement["words"][1:]
    where = ("these records cannot place it" if placement["subsystem"] == "none" else
             f"the gap starts in the <b>{html.escape(placement['subsystem'])}</b>")
    return (f"<h3>Where it starts (experiments on the records with the final model)</h3>"
            f"<p>{html.escape(words)}: {where}. Each experiment changes one thing the "
            f"model is told and fits it on the training data; a change of one signal that "
            f"removes at least {100 * placement['places_at']:.0f} % of the held-out gap places "
            f"the cause there, else the subsystem whose replay with measured inputs still "
            f"misses does; with too few sensors for the replays, the candidate that explains "
            f"most of the gap.</p>" + placement_figure(placement))


def calibration_figure(result: dict) -> str:
    """Each calibration knob's factor against nominal [%]: the final model's and the
    recalibration's alone, with the search range."""
    from jetpipe_ros.diagnosis.calibration import CALIBRATION

    plt = pyplot()
    cal = result["calibration"]
    knobs = [k.name for k in CALIBRATION.knobs]
    y = np.arange(len(knobs))[::-1]
    fig, ax = plt.subplots(figsize=(8, 0.32 * len(knobs) + 1.2))
    for k, yi in zip(CALIBRATION.knobs, y):
        ax.plot([100 * (k.low - 1), 100 * (k.high - 1)], [yi, yi], color="#dddddd", lw=6,
                solid_capstyle="butt", zorder=0)
    alone = [100 * (cal["recalibration_alone"][k] - 1) for k in knobs]
    final = [100 * (cal["knobs"][k] - 1) for k in knobs]
    ax.scatter(alone, y, marker="o", facecolors="none", edgecolors="#888888",
               label="recalibration alone", zorder=2)
    ax.scatter(final, y, marker="D", color=COLORS["augmented"] if cal["significant"]
               else "#bbbbbb", label="in the augmented model" if cal["significant"]
               else "with the effect (not significant)", zorder=3)
    ax.axvline(0.0, color="#444444", lw=0.8)
    ax.set_yticks(y, knobs, fontsize=8)
    ax.set_xlabel("factor against nominal [%] (grey band: search range)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return png_img(fig)


def overlay_figure(prepared: Prepared, preds: dict, result: dict, augmented: bool) -> str:
    """Data, nominal and, when it is another model (``augmented``), augmented model on the
    held-out experiment with the largest gap."""
    plt = pyplot()
    best, worst = None, -1.0
    for i, rec in enumerate(prepared.records):
        if not rec.holdout.any():
            continue
        p = preds["nominal"][i]
        m = p.free & rec.holdout
        err = np.mean([np.mean(((p.signal(s) - rec.signal(s)) / prepared.scale[s])[m] ** 2)
                       for s in rec.signals()])
        if err > worst:
            best, worst = i, err
    if best is None:
        return ""
    rec = prepared.records[best]
    signals = rec.signals()
    fig, axes = plt.subplots(len(signals) + 1, 1, figsize=(10, 2.0 * (len(signals) + 1)),
                             sharex=True)
    units = {"y": ("position [mm]", 1e3), "p1": ("p1 [bar]", 1e-5), "p2": ("p2 [bar]", 1e-5)}
    # The record's start that no comparison uses (the replay of an unmeasured chamber still
    # depending on where it started: prediction.unknown_start).
    start = int(np.argmax(rec.train | rec.holdout))
    for ax, s in zip(axes, signals):
        label, k = units[s]
        if start > 1:
            ax.axvspan(rec.t[0], rec.t[start], color="0.88", lw=0, label="not compared")
        ax.plot(rec.t, rec.signal(s) * k, color=COLORS["data"], lw=1.2, label="data")
        for name in ("nominal", "augmented") if augmented else ("nominal",):
            ax.plot(rec.t, preds[name][best].signal(s) * k, color=COLORS[name], lw=0.9,
                    label=name)
        ax.set_ylabel(label)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title(f"held-out experiment '{rec.name}' (predictions restart from the "
                      f"measurements every {result['localization']['horizon_s']:g} s)")
    axes[-1].plot(rec.t, rec.u, color="#2ca02c", lw=0.8)
    axes[-1].set_ylabel("command [V]")
    axes[-1].set_xlabel("time [s]")
    return png_img(fig)


#: The coverage chart's samples: fitted on, judged on, left out of every comparison, and the
#: rows a logger lost among them (drawn as ticks: one row is too narrow for a bar).
COVERAGE = {"train": ("#1f77b4", "training"), "holdout": ("#ff7f0e", "held out"),
            "neither": ("#d9d9d9", "not compared"),
            "lost": ("#d62728", "not compared: a row the logger lost")}


def not_compared(rec: Record) -> tuple[int, np.ndarray]:
    """The samples of ``rec`` no comparison uses: its first compared sample (before it, the
    start: while an unmeasured chamber's start still matters,
    :func:`~jetpipe_ros.diagnosis.prediction.without_unknown_start`, or rows lost there), and
    the rows left out after it, the rows a logger lost (the masks hold measured rows only)."""
    compared = rec.train | rec.holdout
    if not compared.any():
        return compared.size, np.zeros(0, dtype=int)
    first = int(np.argmax(compared))
    return first, first + np.flatnonzero(~compared[first:])


def coverage_figure(prepared: Prepared) -> str:
    """Which samples of each experiment the diagnosis compared, training or held out, and which
    none (:func:`not_compared`). An experiment split at a long gap is two lanes."""
    plt = pyplot()
    from matplotlib.patches import Patch  # after pyplot(): matplotlib is imported on first use
    records = prepared.records
    if not records:
        return ""
    fig, ax = plt.subplots(figsize=(10, 0.28 * len(records) + 1.1))
    dt = prepared.dt
    drawn = set()  # the kinds of COVERAGE the chart shows: its legend's
    for lane, rec in enumerate(records):
        kind = np.where(rec.train, 0, np.where(rec.holdout, 1, 2))
        edges = np.flatnonzero(np.diff(kind)) + 1
        starts, ends = np.r_[0, edges], np.r_[edges, kind.size]
        for name, k in (("train", 0), ("holdout", 1), ("neither", 2)):
            runs = [(rec.t[a], (b - a) * dt) for a, b in zip(starts, ends) if kind[a] == k]
            if runs:
                ax.broken_barh(runs, (lane - 0.38, 0.76), color=COVERAGE[name][0], lw=0)
                drawn.add(name)
        compared = rec.train | rec.holdout
        _, lost = not_compared(rec)
        if lost.size:
            ax.vlines(rec.t[lost], lane - 0.38, lane + 0.38, color=COVERAGE["lost"][0], lw=0.6)
            drawn.add("lost")
        ax.text(rec.t[-1] + dt, lane, f" {100 * compared.mean():.0f} %", va="center",
                fontsize=7)
    ax.set_yticks(range(len(records)), [r.name for r in records], fontsize=7)
    ax.set_ylim(len(records) - 0.5, -0.5)
    ax.set_xlabel("time in the experiment [s] (right: share of its samples compared)")
    ax.legend(handles=[Patch(color=COVERAGE[k][0], label=COVERAGE[k][1])
                       for k in COVERAGE if k in drawn],
              fontsize=8, loc="upper left", bbox_to_anchor=(1.04, 1.0))
    fig.tight_layout()
    return png_img(fig)


def regime_figure(result: dict) -> str:
    """Held-out gap per operating regime, nominal against augmented."""
    plt = pyplot()
    reg = result["localization"]["regimes"]
    names = [n for n in reg if "nominal" in reg[n]]
    if not names:
        return ""
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(9, 3.2))
    for j, label in enumerate(("nominal", "augmented")):
        vals = [reg[n].get(label, {}).get("gap", 0.0) for n in names]
        ax.bar(x + (j - 0.5) * 0.38, vals, 0.38, color=COLORS[label], label=label)
    ax.set_xticks(x, [f"{n}\n{100 * reg[n]['share']:.0f} % of data" for n in names],
                  fontsize=8)
    ax.set_ylabel("held-out gap [%]")
    ax.legend()
    return png_img(fig)


#: The frequency response's output signals: (what, unit of its gain).
RESPONSE = {"p1": ("chamber 1 pressure", "Pa/V"), "p2": ("chamber 2 pressure", "Pa/V"),
            "y": ("position", "m/V")}


def frequency_figure(result: dict, augmented: bool) -> str:
    """Bode plot, command to the signal the diagnosis chose (chamber 1's pressure, else the
    one there is): data, nominal and, when it is another model (``augmented``), augmented."""
    plt = pyplot()
    fr = result["localization"]["frequency"]
    if not fr or not fr.get("freq"):
        return ""
    what, unit = RESPONSE[fr["signal"]]
    f = np.array(fr["freq"])
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for name in ("data", "nominal", "augmented") if augmented else ("data", "nominal"):
        style = dict(color=COLORS[name], lw=1.0, ms=4 if name == "data" else 2,
                     marker="o" if name == "data" else ".", ls="none" if name == "data"
                     else "-")
        a1.semilogx(f, 20 * np.log10(np.maximum(np.array(fr["gain"][name]), 1e-300)),
                    label=name, **style)
        a2.semilogx(f, np.array(fr["phase_deg"][name]), **style)
    a1.set_ylabel(f"gain [dB {unit}]")
    a2.set_ylabel("phase [deg]")
    a2.set_xlabel("frequency [Hz]")
    # Plain labels where the bands meet (matplotlib's minor log labels overlap at 3-4 Hz).
    ticks = [t for t in (2, 5, 10, 20, 50) if f[0] <= t <= f[-1]]
    a2.set_xticks(ticks, [f"{t:g}" for t in ticks])
    a2.set_xticks([], minor=True)
    a1.legend(fontsize=8)
    a1.set_title(f"command to {what}: open-loop experiments, bins where the data are "
                 f"coherent")
    return png_img(fig)


def _without_caveats(reason: str) -> str:
    """A verdict's reason without what it cannot rule out, which the summary says apart."""
    for caveat in (NOT_RULED_OUT, FAVOURED):
        reason = reason.split("; " + caveat)[0]
    return reason


def summary(result: dict) -> str:
    """The plain-language summary at the top of the report."""
    v = result["verdict"]
    g = result["gap"]
    cal = result["calibration"]
    lines = []
    off = ", ".join(cal["summary"]) or "all within 2 % of nominal"
    signs = result["data"].get("signs")
    if signs and signs["against_as_logged"]:
        lines.append(f"<b>Signs ({'corrected' if signs['changes'] else 'as logged'}):</b> "
                     f"{html.escape(signs['explanation'])}.")
    base = result["data"].get("time_base")
    if base and base["reading"] != "aligned":
        lines.append(f"<b>Time base ({html.escape(base['reading'])}):</b> "
                     f"{html.escape(base['explanation'])}.")
    if not v.get("model_fits", True):
        lines.append(f"<b>The model does not describe this hardware.</b> "
                     f"{html.escape(v['reason'])}. No effect is named.")
    elif v["effect"] == "none":
        # What the answer cannot rule out is said below ("Not ruled out"), with a table.
        reason = _without_caveats(v["reason"]).removeprefix(NO_EFFECT)
        lines.append(f"<b>No unmodelled effect identified:</b> {html.escape(reason)}.")
    elif v["effect"] == "unlisted":
        lines.append(f"<b>A gap beyond noise remains that no listed effect explains</b> "
                     f"(<code>unlisted</code>, subsystem {html.escape(v['subsystem'])}): "
                     f"{html.escape(_without_caveats(v['reason']))}.")
        if v["partial"]:
            lines.append(f"The best candidate, <code>{html.escape(v['partial']['candidate'])}"
                         f"</code>, removes only {100 * v['partial']['shrinkage']:.0f} % of it: "
                         f"at most part of the cause.")
    else:
        params = v["params"] if len(v["effects"]) == 1 else {
            f"{e}.{k}": x for e, d in v["params"].items() for k, x in d.items()}
        errs = v["stderr"] if len(v["effects"]) > 1 else v["stderr"].get(v["effects"][0], {})
        flat_err = {f"{e}.{k}": x for e, d in errs.items() for k, x in d.items()} \
            if len(v["effects"]) > 1 else errs
        ptxt = ", ".join(f"{k} = {x:.4g}" + (f" +- {flat_err[k]:.2g}" if flat_err.get(k)
                                              else "") for k, x in params.items())
        if cal["significant"]:
            lines.append(f"<b>The nominal parameters were off</b> ({html.escape(off)}), "
                         f"<b>and on top of that <code>{html.escape(v['effect'])}</code></b> "
                         f"({html.escape(v['subsystem'])}; {html.escape(ptxt)}) explains "
                         f"what recalibration leaves, confidence {v['confidence']:.2f}.")
        else:
            lines.append(f"<b>The gap is best explained by <code>{html.escape(v['effect'])}"
                         f"</code></b> ({html.escape(v['subsystem'])}; {html.escape(ptxt)}), "
                         f"confidence {v['confidence']:.2f}; the nominal parameters need no "
                         f"correction beyond noise.")
        for effect, cmp in v["form_comparison"].items():
            gaps = cmp["holdout_gap"]
            others = [f"{f} {g:.2f} %" for f, g in gaps.items() if f != cmp["chosen"]]
            rest = (f"; the other form{'s' if len(others) > 1 else ''}: "
                    f"{html.escape(', '.join(others))}" if others else "")
            lines.append(f"Form of <code>{html.escape(effect)}</code>: <b>"
                         f"{html.escape(cmp['chosen'])}</b> (held-out gap "
                         f"{gaps.get(cmp['chosen'], float('nan')):.2f} %{rest}).")
        for told in (loop_words(v), port_words(v)):
            if told:
                lines.append(html.escape(told))
        lines.append(f"What the effect leaves of the gap it was judged against: "
                     f"{100 * v['remaining_share']:.0f} %.")
        words = v["effect_reason"]
        if cal["significant"] and cal["shrinkage_given_effect"] is not None:
            words += (f"; recalibrating the nominal parameters as well removes "
                      f"{100 * cal['shrinkage_given_effect']:.0f} % of what the effect alone "
                      f"leaves")
        lines.append(html.escape(_capital(words)) + ".")
    if cal["significant"] or v["effect"] != "none":
        lines.append(f"Recalibration alone takes the held-out gap from {cal['gap_before']:.2f} "
                     f"% to {cal['gap_after']:.2f} %; the augmented model (what "
                     f"<code>augmented.yaml</code> runs) from {g['nominal']:.2f} % to "
                     f"{g['augmented']:.2f} % ({100 * g['shrinkage']:.0f} % smaller).")
    if cal["at_bound"]:
        lines.append("Recalibration stopped at the bound of "
                     + ", ".join(f"<code>{k}</code> ({cal['knobs'][k]:.2f} x nominal)"
                                 for k in cal["at_bound"])
                     + ": the truth may lie outside the range searched, or the knob stands in "
                       "for something it does not model.")
    free = nuisance_words(cal["nuisance"]) if cal.get("nuisance") else None
    if free:
        lines.append(html.escape(_capital(free)) + ".")
    if cal["traded_with_effect"]:
        lines.append("With the effect in the model, recalibration moved "
                     + ", ".join(f"<code>{k}</code> by {100 * (m - 1):+.0f} %"
                                 for k, m in cal["traded_with_effect"].items())
                     + ": these knobs and the effect partly stand in for each other in "
                       "these experiments.")
    for row in cal.get("stand_ins", []):
        if row["preferred"] in ("recalibration", "no effect"):  # else in the verdict's reason
            lines.append("Could a knob that moved stand in for an effect? "
                         + html.escape(stand_in_words(row)) + ".")
        elif row["separating_experiment"] and not row["separating_experiment"]["in_dataset"]:
            lines.append(_campaign_entry(row["separating_experiment"]))
    sep = v["separating_experiment"]
    alt = v["ambiguous_with"] or (v["alternative"] or {}).get("explanation")
    if alt:
        where = ("of this dataset; a longer run of it" if sep["in_dataset"] else
                 "designed for it, not in this dataset; recording it" if sep["designed"] else
                 "of the default campaign (config/campaign.yaml), not in this dataset; "
                 "recording it") if sep else ""
        extra = (f" The experiment '{html.escape(sep['experiment'])}' {where} would "
                 f"separate them best (their predictions differ by "
                 f"{sep['difference_over_noise']:.1f} x the sensor noise)." if sep else "")
        # A pressure the bench did not log, where the two differ by more than one reading's
        # noise (RMS over the dataset's own experiments): a sensor that would tell them apart.
        logged = {k: x for k, x in (sep or {}).get("with_sensors", {}).items() if x >= 1.0}
        if logged:
            extra += (" Logged with " + " or ".join(f"{ADDED[k]} pressure" for k in logged)
                      + ", these very experiments would tell them apart too: the two models' "
                      "predictions of it differ by " + " and ".join(
                          f"{x:.1f}" for x in logged.values()) + " x a pressure sensor's noise.")
        lines.append(f"But <code>{html.escape(alt)}</code> explains the data almost as well: "
                     f"these experiments cannot tell the two apart." + extra)
        if sep and not sep["in_dataset"]:
            lines.append(_campaign_entry(sep))
    sig = result["localization"]["signals"]["nominal"]
    worst = max((k for k in sig if k != "gap"), key=lambda k: sig[k], default=None)
    if worst:
        lines.append(f"Before correction the gap lies mostly in <b>{worst}</b> "
                     f"({sig[worst]:.2f} %).")
    reg = result["localization"]["regimes"]
    if reg:
        top = max(reg, key=lambda n: reg[n].get("nominal", {}).get("gap", 0.0))
        lines.append(f"By regime it is largest when <b>{top.replace('_', ' ')}</b> "
                     f"({reg[top]['nominal']['gap']:.2f} %).")
    named = [h for h in result["visibility"]["too_small_to_see"]
             if h.split(":")[0] in v["effects"]]
    hidden = [h for h in result["visibility"]["too_small_to_see"] if h not in named]
    if hidden:
        lines.append("At their typical size these effects would not show in these "
                     "experiments (the data cannot tell): "
                     + ", ".join(f"<code>{h}</code>" for h in hidden) + ".")
    if named:
        lines.append("At its typical size the named effect (" + ", ".join(
            f"<code>{h}</code>" for h in named) + ") would not show in these experiments "
            "either: what it explains here is small (see above).")
    hidden_at_any_size = unseen(result["visibility"].get("smallest_shown", {}))
    if hidden_at_any_size:
        lines.append("Not shown at any size within its search range, so this answer says "
                     "nothing of: " + ", ".join(f"<code>{c}</code>" for c in hidden_at_any_size)
                     + "; the smallest size of each other candidate these records would show "
                     "is in <i>What these experiments can show</i>.")
    elif result["visibility"].get("smallest_shown"):
        lines.append("The smallest size of each candidate these records would show is in "
                     "<i>What these experiments can show</i>.")
    hidden = imitated_effects(result["visibility"].get("imitated_by_recalibration", {}))
    imitated = [e for e in result["visibility"].get("not_ruled_out", []) if e in hidden]
    if imitated:
        lines.append("<b>Not ruled out</b> by this answer: "
                     + ", ".join(f"<code>{e}</code>" for e in imitated)
                     + ". At its typical size the recalibration imitates each on these records "
                     "(see <i>What these experiments can show</i>): "
                     + _what_would_tell(result, imitated))
    lines += [_favoured_words(row) for row in result["visibility"].get(
        "favoured_by_all_records", []) if row["favoured"]]
    return "<p>" + "</p><p>".join(lines) + "</p>"


def _favoured_words(row: dict) -> str:
    """A candidate the records as a whole favour and the held-out ones cannot confirm
    (:mod:`jetpipe_ros.diagnosis.pooled`), in words."""
    return (f"<b>Not ruled out</b> either: <code>{row['candidate']}</code>, which the records "
            f"as a whole favour. Fitted on every record, training and held-out, it leaves "
            f"{row['pooled_gap']:.2f} % where the recalibration leaves "
            f"{row['recalibration_pooled_gap']:.2f} %. Fitted on the training records alone "
            f"it leaves {row['train_gap']:.2f} % of them (the recalibration "
            f"{row['recalibration_train_gap']:.2f} %) but {row['holdout_gap']:.2f} % held out "
            f"(the recalibration {row['recalibration_holdout_gap']:.2f} %): what it predicts "
            f"there rests on what the training records leave free, so the held-out "
            f"experiments cannot confirm it. A training record like "
            f"<code>{html.escape(row['decisive_record'])}</code> would decide it.")


def loop_words(verdict: dict) -> str | None:
    """The named valve hysteresis's loop in words: its plays' thresholds [V] and the share of
    the loop each holds, as the augmented model runs them (``spread`` and ``sharp_share`` are
    knobs, not what a user sees in a measured loop). None when no hysteresis is named."""
    if "valve_hysteresis" not in verdict["effects"]:
        return None
    values = (verdict["params"] if len(verdict["effects"]) == 1
              else verdict["params"]["valve_hysteresis"])
    r, w = hysteresis_plays(CANDIDATES["valve_hysteresis"].apply(ModelParams(), values))
    if r.size == 0:
        return None
    words = f"The hysteresis loop found: {r.size} play operators"
    if np.ptp(r) < LOOP_RESOLUTION:
        return words + f" at one threshold, {r[0]:.3f} V: one sharp loop."
    words += (f" with thresholds from {r.min():.3f} to {r.max():.3f} V (weighted mean "
              f"{w @ r:.3f} V: the half-width of a loop the command runs through in full)")
    end = int(np.argmax(w))
    if np.ptp(w) < 0.005:
        return words + ", each holding an equal share of the loop: a rounded loop."
    rest = np.delete(r, end)
    return (words + f"; its {'narrowest' if end == 0 else 'widest'} play ({r[end]:.3f} V) "
            f"holds {100 * w[end]:.0f} % of the loop, the other {rest.size} "
            f"({rest.min():.3f} to {rest.max():.3f} V) {100 * np.delete(w, end).max():.0f} % each. "
            f"When the command turns back, each play's share of the valve's output stays put "
            f"until the command has moved twice that play's threshold.")


def port_words(verdict: dict) -> str | None:
    """The named port (``valve_lag``, ``form: port``) in words: its volume, its restriction as
    a catalogue gives it (sonic conductance, subsonic index m) and what m makes of it (0.5 an
    orifice or a fitting, 1 a porous element; each told only when the other lies beyond two
    standard errors of the fitted m), and its time constant at rest
    (:func:`~jetpipe_ros.model.actuator.port_time_constant`). None when no port is named."""
    if (verdict.get("forms") or {}).get("valve_lag") != "port":
        return None
    values = (verdict["params"] if len(verdict["effects"]) == 1
              else verdict["params"]["valve_lag"])
    m = values["port_index"]
    sigma = (verdict.get("stderr") or {}).get("valve_lag", {}).get("port_index") or 0.0
    orifice, porous = (abs(m - end) <= max(2.0 * sigma, 0.01) for end in (0.5, 1.0))
    if orifice and porous:
        kind = "the records do not tell an orifice (m = 0.5) from a porous element (m = 1)"
    elif orifice:
        kind = "an orifice or a fitting (the drop grows as the flow squared)"
    elif porous:
        kind = ("a porous element such as a sintered filter (Darcy: the drop linear in the flow, "
                "the conductance growing with the mean pressure)")
    else:
        kind = "between an orifice (m = 0.5) and a porous element (m = 1)"
    tau = port_time_constant(CANDIDATES["valve_lag:port"].apply(ModelParams(), values))
    spread = f" +- {sigma:.2f}" if sigma else ""
    return (f"The port found: {values['port_volume'] * 1e6:.1f} cm^3 before each chamber "
            f"behind a restriction of sonic conductance "
            f"{values['port_conductance'] * 1e8:.2g} dm^3/(s bar) (ISO 6358) and subsonic "
            f"index m = {m:.2f}{spread}: {kind}. At rest the port's pressure follows the "
            f"valve's flow with a time constant of {tau * 1e3:.1f} ms.")


#: Thresholds closer than this [V] read as one sharp loop: a tenth of the smallest typical
#: half-width (0.1 V, docs/effects.md), below what the loop's position shows.
LOOP_RESOLUTION = 0.01


def _limit_cell(limit: dict) -> _Html:
    """A detection limit (:func:`jetpipe_ros.diagnosis.detection.detection_limit`) for the
    table of what the experiments can show: the size and the parameters there, or why there is
    none."""
    values = _values_text(limit["values"])
    if limit["times_typical"] is None:
        return _Html(f"<div class='params'>{html.escape(limit['note'])} ({values})</div>")
    return _Html(f"<div class='params'>{limit['times_typical']:.2g} ({values})</div>")


def _what_would_tell(result: dict, effects: list[str]) -> str:
    """Which record would tell ``effects`` (not ruled out) from parameters that are off: the
    pressure sensors that would on the same experiments (``with_sensors``), else another
    sensor or experiment."""
    rows = imitated_effects(result["visibility"].get("imitated_by_recalibration", {}))
    by: dict[str, list[str]] = {}
    for e in effects:
        key = " or ".join(f"{ADDED[k]} pressure{'s' if '+' in k else ''}"
                          for k in telling(rows.get(e, {}).get("with_sensors", {})))
        by.setdefault(key, []).append(f"<code>{e}</code>")
    words = [f"logged with {key} as well, these experiments would tell {', '.join(es)}"
             for key, es in by.items() if key]
    if "" in by:
        words.append(f"a record with another sensor or experiment is needed to tell "
                     f"{', '.join(by[''])}")
    return "; ".join(words) + "."


#: Longest list of corrections shown open; a longer one (a logger that lost rows in every file
#: says so file by file) is folded, the chart of compared samples drawing the same at a glance.
OPEN_CORRECTIONS = 6


def _corrections(data: dict) -> str:
    """The time base as read, then what the reader corrected, the same words of several files
    said once (:func:`~jetpipe_ros.dataset.grouped_notes`), folded when there are many."""
    base = data["time_base"]
    notes = grouped_notes(data.get("corrections", []))
    items = "".join(f"<li>{html.escape(c)}</li>" for c in notes)
    out = (f"<p>Time base ({html.escape(base['reading'])}): "
           f"{html.escape(base['explanation'])}.</p>")
    if len(notes) > OPEN_CORRECTIONS:
        return (out + f"<details><summary>{len(notes)} corrections of the records, file by "
                f"file</summary><ul>{items}</ul></details>")
    return out + (f"<ul>{items}</ul>" if notes else "")


def _capital(words: str) -> str:
    """``words`` with a capital first letter, unless they start with a name of the package's
    vocabulary (``friction_dynamics:lugre``), which keeps its spelling."""
    first = words.split(" ", 1)[0]
    return words if "_" in first or ":" in first else words[0].upper() + words[1:]


def _campaign_entry(sep: dict) -> str:
    """The campaign entry of a separating experiment not in the dataset (YAML for
    ``config/campaign.yaml`` and ``id_recorder``)."""
    entry = yaml.safe_dump([sep["campaign_entry"]], sort_keys=False, default_flow_style=None)
    return (f"To record '{html.escape(sep['experiment'])}', add it to the campaign's "
            f"<code>experiments:</code> (<code>id_recorder</code>, docs/node.md):"
            f"<pre>{html.escape(entry)}</pre>")


def equation_words(result: dict) -> str:
    """The equation-error finding in words (:func:`residuals.describe`)."""
    from jetpipe_ros.diagnosis.residuals import describe

    return _capital(describe(result["localization"]["equations"]))


def _table(rows: list[list], header: list[str]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_cell(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<div class='wide'><table><tr>{head}</tr>{body}</table></div>"


@dataclass(frozen=True)
class _Html:
    """A table cell already in HTML."""

    text: str


def _params_cell(params: dict) -> _Html:
    """Fitted parameters of a ranking row: the effect's (a pair's prefixed with their effect)
    in the open, the calibration knobs fitted beside them folded away (the augmented model's
    are in the calibration figure); neither spread over the row's width."""
    flat, knobs = {}, {}
    effects = [k for k, v in params.items() if isinstance(v, dict) and k != CALIBRATION_GROUP]
    for k, v in params.items():
        if k == CALIBRATION_GROUP and isinstance(v, dict):
            knobs = v
        elif isinstance(v, dict):  # a pair's knobs under their effect's name
            flat.update({f"{k}.{kk}" if len(effects) > 1 else kk: vv for kk, vv in v.items()})
        else:
            flat[k] = v

    folded = (f"<details><summary>calibration</summary>{_values_text(knobs)}</details>"
              if knobs else "")
    return _Html(f"<div class='params'>{_values_text(flat)}{folded}</div>")


def _values_text(values: dict) -> str:
    """Parameters as ``name=value`` (3 digits), escaped; what is not a number left out."""
    return html.escape(", ".join(f"{k}={v:.3g}" for k, v in values.items()
                                 if isinstance(v, (int, float))))


def _breakable(name: str) -> _Html:
    """A candidate's name that may wrap after its ':' and '+' (a long one had widened the
    ranking table past the page)."""
    return _Html(html.escape(name).replace(":", ":<wbr>").replace("+", "+<wbr>"))


def _noise_words(signal: str, sigma: float) -> str:
    """A measured signal's estimated white noise in words: ``sigma`` in m or Pa."""
    return (f"position {sigma * 1e6:.1f} um" if signal == "y" else
            f"chamber {signal[1]} pressure {sigma:.0f} Pa")


def _cell(c) -> str:
    if isinstance(c, _Html):
        return c.text
    if isinstance(c, float):
        return f"{c:.4g}"
    if c is None:
        return "-"
    return html.escape(str(c))


def equations_figure(result: dict, remainders: dict) -> str:
    """Each equation's error beyond its calibration-shaped part, blocked over 50 ms, against the
    library term that carries most of it (or over the blocks when none does): the shape of what
    the model misses."""
    plt = pyplot()
    eqs = result["localization"]["equations"]["equations"]
    names = [n for n in eqs if n in remainders]
    if not names:
        return ""
    fig, axes = plt.subplots(1, len(names), figsize=(4.0 * len(names), 3.4), squeeze=False)
    for ax, name in zip(axes[0], names):
        e = remainders[name]
        info = eqs[name]
        scale = 1e3 if e.unit == "kg/s" else 1.0
        unit = "g/s" if e.unit == "kg/s" else e.unit
        terms = info["terms"]
        term = next((t for t in e.terms if terms and t.name == terms[0]["term"]), None)
        if term is not None and np.std(term.values) > 0:
            ax.plot(term.values, e.error * scale, ".", ms=2, color="#1f77b4", alpha=0.5)
            ax.set_xlabel(term.name)
        else:
            ax.plot(e.error * scale, ".", ms=2, color="#888888", alpha=0.5)
            ax.set_xlabel("50-ms block")
        beyond = info["over_noise"] >= result["localization"]["equations"]["beyond_noise"]
        ax.set_title(f"{name}\n{info['over_noise']:.1f} x noise"
                     + (" (beyond noise)" if beyond else ""), fontsize=9,
                     color=COLORS["nominal"] if beyond else "#222222")
        ax.set_ylabel(f"error [{unit}]")
    fig.tight_layout()
    return png_img(fig)


def render(result: dict, prepared: Prepared, preds: dict, remainders: dict) -> str:
    """The report as an HTML string."""
    loc = result["localization"]
    sig_rows = [[s, loc["signals"]["nominal"].get(s), loc["signals"]["augmented"].get(s)]
                for s in ("gap", "y", "p1", "p2") if s in loc["signals"]["nominal"]]
    sub = loc["subsystems"]
    unjudged = "not judged: too few sensors"
    sub_rows = [["valve and chambers (driven by measured motion)",
                 sub["valve_and_chambers"]["gap"] if sub["valve_and_chambers"] else unjudged],
                ["mechanics (driven by measured pressures)",
                 sub["mechanics"]["gap"] if sub["mechanics"] else unjudged],
                ["sensors: steady pressure offset [Pa]",
                 sub["sensors"]["steady_pressure_offset_pa"]]]
    paper = result["gap"]["paper_metrics"]
    metric_rows = [[k, paper["nominal"].get(k), paper["augmented"].get(k)]
                   for k in paper["nominal"]]
    # The second fold (fitted on the holdout, judged on the training data) is run only for an
    # ambiguous verdict's two rows: its column is shown only then.
    folds = any(r.get("second_fold_gap") is not None for r in result["ranking"])
    rank_rows = [[_breakable(r["candidate"]), r["subsystem"], r["train_gap"], r["holdout_gap"],
                  *([r.get("second_fold_gap")] if folds else []),
                  f"{100 * r['shrinkage']:.0f} %", r["t"], r["t_cross_check"],
                  ("yes, left out: " + r["left_out"] if r.get("left_out") else
                   "yes" if r["explains"] else "no"),
                  f"{100 * r['alone']['shrinkage']:.0f} %" if r["alone"] else None,
                  _params_cell(r["params"])]
                 for r in result["ranking"]]
    cal = result["calibration"]
    cal_rows = [[k, ", ".join(cal["parameters"][k]), f"{x:.3f}",
                 f"{cal['recalibration_alone'][k]:.3f}"] for k, x in cal["knobs"].items()]
    vis = result["visibility"]["at_typical_size_gap_pct"]
    imitated = result["visibility"].get("imitated_by_recalibration", {})
    # With a chamber pressure missing: what the imitation would leave with it logged.
    added = any("with_sensors" in row for row in imitated.values())
    # For a verdict of no effect: the smallest size of each candidate these records show.
    limits = result["visibility"].get("smallest_shown", {})
    vis_rows = [[e, x, "yes" if x >= result["visibility"]["threshold_gap_pct"] else "no",
                 imitated[e]["left_gap_pct"] if e in imitated else "-",
                 *([", ".join(f"{k} {v:.2f}" for k, v in
                              imitated.get(e, {}).get("with_sensors", {}).items()) or "-"]
                   if added else []),
                 *([_limit_cell(limits[e]) if e in limits else "-"] if limits else [])]
                for e, x in vis.items()]
    data = result["data"]
    sensors = data.get("sensors", ["y", "p1", "p2"])
    exp_rows = [[e["name"], e["piston"], e["train_s"], e["holdout_s"]]
                for e in data["experiments"]]
    style = ("body{font-family:sans-serif;max-width:1200px;margin:2em auto;color:#222}"
             "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #ccc;"
             "padding:2px 8px;font-size:90%}th{background:#f2f2f2}img{max-width:100%}"
             ".params{overflow-wrap:anywhere;min-width:12em}.wide{overflow-x:auto}"
             ".summary{background:#f5f8fc;border-left:4px solid #1f77b4;padding:0.5em 1em}")
    # The augmented predictions are another model's (the diagnosis hands over the nominal
    # predictions themselves when it fitted none)
    augmented = preds["augmented"] is not preds["nominal"]
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>jetpipe diagnosis: {html.escape(result['verdict']['effect'])}</title>",
        f"<style>{style}</style></head><body>",
        "<h1>Sim-to-real gap diagnosis</h1>",
        f"<div class='summary'>{summary(result)}</div>",
        "<h2>Calibration: nominal parameters that are off</h2>",
        "<p>Lumped knobs recalibrated on the training experiments, each a factor on the "
        "nominal parameters (1 = nominal). Significant when it removes a significant part of "
        "the held-out gap, and, with an effect, of what the effect alone leaves.</p>",
        calibration_figure(result),
        _table(cal_rows, ["knob", "multiplies", "factor", "recalibration alone"]),
        "<h2>Which effect explains the gap</h2>",
        "<p>Each candidate fitted on the training experiments on top of the recalibrated model "
        "(the best jointly with the calibration knobs), judged on the held-out ones against "
        "the recalibrated model; 'alone' = fitted on the nominal model, judged against it. "
        "Gap = RMS prediction error beyond sensor noise, in % of each signal's spread, over "
        f"{loc['horizon_s']:g}-s prediction horizons.</p>",
        ranking_figure(result),
        _table(rank_rows, ["candidate", "subsystem", "train gap %", "held-out gap %",
                           *(["second fold gap %"] if folds else []),
                           "shrinkage", "paired t", "t cross-check", "explains",
                           "shrinkage alone", "fitted parameters"]),
        *(f"<p>Not ruled out: <code>{html.escape(row['candidate'])}</code>, which the records "
          f"as a whole favour (the summary). Each held-out record's gap under the "
          f"recalibration and under the candidate fitted on the training records and on every "
          f"record:</p>" + favoured_figure(row)
          for row in result["visibility"].get("favoured_by_all_records", [])
          if row["favoured"] and row.get("by_record")),
        "<h2>Model against data</h2>", overlay_figure(prepared, preds, result, augmented),
        "<h2>Where the gap lies</h2>", "<h3>By regime (held out)</h3>",
        regime_figure(result), "<h3>By frequency</h3>", frequency_figure(result, augmented),
        "<h3>By equation (what the augmented model's equations leave, all data)</h3>",
        f"<p>{html.escape(equation_words(result))}.</p>",
        equations_figure(result, remainders),
        placement_section(loc["placement"]) if "placement" in loc else "",
        "<h3>By signal (held out, %)</h3>",
        _table(sig_rows, ["signal", "nominal", "augmented"]),
        "<h3>By subsystem (nominal model, all data, %)</h3>",
        _table(sub_rows, ["subsystem replayed alone", "gap"]),
        "<h3>The paper's metrics (held out)</h3>",
        f"<p>Gain and phase errors of the response from the command to the "
        f"{RESPONSE[loc['frequency']['signal']][0]}, over the open-loop experiments.</p>"
        if loc["frequency"] else "",
        _table(metric_rows, ["metric", "nominal", "augmented"]),
        "<h2>What these experiments can show</h2>",
        "<p>Signature of each candidate at its typical size: the held-out gap [%] it would open "
        "on these experiments; below the 0.5 % that counts as beyond noise the data cannot tell "
        "whether it is there. The column <i>left after the knobs imitate it</i> is what is left "
        "of it once the recalibration's knobs imitate it as best they can: below 0.5 %, an "
        "answer of no effect does not rule it out."
        + (" For those, the column <i>left were these pressures logged too</i> is what would be "
           "left on the same experiments had the rig also logged a chamber's pressure (p1, p2) "
           "or both: above 0.5 %, that sensor would tell it from parameters that are off."
           if added else "") + "</p>",
        *(["<p>No effect was named: the last column is the smallest size of each candidate "
           "these records would show, as a multiple of its typical size and its parameters "
           "there (SI units): the size at which what is left once the knobs imitate it reaches "
           "0.5 %. From it on the effect stands out beyond noise after any recalibration, so "
           "this answer speaks against it; the diagnosis' own tests often find smaller "
           "effects (a bound from above, a linear check).</p>"] if limits else []),
        _table(vis_rows, ["candidate", "gap at typical size [%]", "visible",
                          "left after the knobs imitate it [%]",
                          *(["left were these pressures logged too [%]"] if added else []),
                          *(["smallest size shown [x typical]"] if limits else [])]),
        "<h2>Data</h2>",
        f"<p>Split: {html.escape(data['split'])}. Sample time {data['sample_time_s'] * 1e3:g} "
        f"ms. Signals measured: {', '.join(sensors)}. Estimated sensor noise: "
        f"{', '.join(_noise_words(s, data['noise'][s]) for s in sensors)}.</p>",
        "".join(f"<p>Note: {html.escape(n)}.</p>" for n in data["notes"]),
        "<h3>What the diagnosis corrected in the records</h3>" + _corrections(data)
        if "time_base" in data else "",
        "".join(f"<p>Not judged: <code>{html.escape(e)}</code>, {html.escape(why)}.</p>"
                for e, why in data.get("cannot_judge", {}).items()),
        "<h3>Which samples were compared</h3>",
        "<p>Each experiment as the diagnosis read it: the samples the models were fitted on, "
        "those they were judged on, and those no comparison uses (rows the logger lost, the "
        "first seconds while a chamber no sensor measured still depends on where it started). "
        "An experiment split at a long gap is two lanes.</p>",
        coverage_figure(prepared),
        _table(exp_rows, ["experiment", "piston", "train [s]", "held out [s]"]),
        "</body></html>",
    ]
    return "\n".join(parts)
