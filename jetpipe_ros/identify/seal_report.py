"""What ``jetpipe friction`` writes: the parameter YAML, the JSON scores, the predictions and a
self-contained HTML report (figures inlined as PNG)."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from jetpipe_ros.dataset.friction_rig import RigRecord
from jetpipe_ros.figures import png_img, pyplot
from jetpipe_ros.identify.drift import Drift, describe, pass_levels
from jetpipe_ros.identify.seal import (DIRECTIONS, FORMS, FormFit, Prepared, SealResult,
                                       measured_presliding, parameter_bounds, reverses,
                                       since_reversal)
from jetpipe_ros.model.flow import P_ATM
from jetpipe_ros.model.friction import LEVEL_FLOOR
from jetpipe_ros.model.params import ModelParams

SCHEMA = "jetpipe.friction/1"
#: The report's words, unit and scale from the fit's units for each parameter.
_SHOWN = {"level": ("sliding level F_C at 0 bar gauge", "N", 1.0),
          "slope": ("its rise per bar of p1 + p2 - 2 p_atm", "N/bar", 1.0),
          "ratio": ("breakaway over sliding level F_S / F_C", "", 1.0),
          "stribeck_velocity": ("Stribeck velocity v_s", "mm/s", 1e3),
          "viscous": ("viscous coefficient F_v", "N s/m", 1.0),
          "presliding_displacement": ("pre-sliding displacement delta", "mm", 1e3),
          "presliding_spread": ("spread of the elements' displacements", "", 1.0),
          "bristle_stiffness": ("bristle stiffness sigma_0", "N/m", 1.0)}
#: A value this close to a bound of its fitted range, relative to the bound (to the range for a
#: bound at 0; in decades for a log-fitted one), is flagged: the bound placed it, not the data.
_AT_BOUND = 1e-3
#: Parameters that follow the pressure: a record's own fit holds its level at its pressure
#: (slope 0), so their range over the records says nothing of the seal's consistency.
_WITH_PRESSURE = ("level", "slope")


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def summary_table(results: list[SealResult]) -> dict[str, dict[str, float]]:
    """Per form: median held-out NRMSE, R^2 and within-direction R^2 over all records."""
    out = {}
    for form in FORMS:
        rows = [s for r in results for s in r.scores[form].values()]
        out[form] = {"median_nrmse": _median([s["nrmse"] for s in rows]),
                     "median_r2": _median([s["r2"] for s in rows]),
                     "median_r2_within": _median([s["r2_within"] for s in rows]),
                     "records": len(rows)}
    return out


def unseen_summary(res: SealResult) -> dict[str, Any] | None:
    """How the selected form's fit carries to a record it did not see: the medians and ranges
    of the records' held-out scores by the seal's fit made without each
    (:attr:`SealResult.unseen`) beside the same records' by their own fits; None with fewer
    than two training records."""
    if not res.unseen:
        return None
    names = list(res.unseen)
    own = [res.scores[res.selected][n] for n in names]
    unseen = [res.unseen[n] for n in names]
    out: dict[str, Any] = {"records": len(names), "form": res.selected,
                           "from_one_pressure": res.unseen_from_one_pressure()}
    for key in ("nrmse", "r2_within"):
        for label, rows in (("unseen", unseen), ("own", own)):
            values = [r[key] for r in rows]
            out[f"{label}_median_{key}"] = _median(values)
            out[f"{label}_range_{key}"] = [float(np.nanmin(values)), float(np.nanmax(values))]
    return out


def describe_unseen(res: SealResult) -> str | None:
    """One line on :func:`unseen_summary`, e.g. "a record judged by the seal's fit made
    without it: held-out NRMSE 3.86 to 19.09 % (median 6.11 %) against 1.86 to 2.35 % (median
    2.18 %) by its own fit; R^2 within direction ..."; None without."""
    u = unseen_summary(res)
    if u is None:
        return None

    def span(label: str, key: str, scale: float, unit: str) -> str:
        lo, hi = (scale * v for v in u[f"{label}_range_{key}"])
        return (f"{lo:.2f} to {hi:.2f}{unit} (median "
                f"{scale * u[f'{label}_median_{key}']:.2f}{unit})" if lo != hi
                else f"{lo:.2f}{unit}")

    flat = u["from_one_pressure"]
    return (f"a record judged by the seal's fit made without it (a pressure or a repeat the "
            f"fit did not see; {u['records']} records, {u['form']}): held-out NRMSE "
            f"{span('unseen', 'nrmse', 100, ' %')} against {span('own', 'nrmse', 100, ' %')} "
            f"by its own fit; R^2 within direction {span('unseen', 'r2_within', 1, '')} "
            f"against {span('own', 'r2_within', 1, '')}"
            + (f"; for {', '.join(flat)} the others lie at one pressure, whose level the fit "
               f"holds (no slope from one pressure): a guess at theirs" if flat else ""))


def to_json(results: list[SealResult], split: float, notes: list[str],
            drifts: dict[str, dict[str, Drift]],
            refused: dict[str, str] | None = None) -> dict[str, Any]:
    """The content of ``friction.json``; ``drifts`` gives each record's level drift by record
    name and direction (:func:`~jetpipe_ros.identify.drift.level_drift`), ``refused`` why each
    seal of the folder not fitted was not (seal -> reason)."""
    refused = refused or {}
    seals = {}
    for res in results:
        records = {}
        for prep in res.preps:
            measured = measured_presliding(prep)
            records[prep.record.name] = {
                "file": prep.record.file, "role": prep.record.role or "train",
                "fitted": prep.record.name in res.per_record[FORMS[0]],
                "mean_pressure_pa": prep.pressure,
                "heldout_moving_samples": int(prep.test.sum()),
                "scores": {form: res.scores[form].get(prep.record.name) for form in FORMS},
                "presliding_displacement_m": {
                    "model": res.model_of(res.selected, prep).presliding,
                    "measured": [float(np.min(measured)), float(np.median(measured)),
                                 float(np.max(measured))] if measured.size else None},
                "level_drift": {d: x.to_json() for d, x in drifts[prep.record.name].items()},
                # The selected form's scores by the seal's fit made without this record.
                "unseen": res.unseen.get(prep.record.name),
                # Its own fit of each form (a fitted record): levels at its pressure (slope 0).
                "parameters": {form: res.per_record[form][prep.record.name].values
                               for form in FORMS if prep.record.name in res.per_record[form]}}
        profile = res.seal_fits[res.selected].profile
        seals[res.seal or "seal"] = {
            "selected": res.selected, "unfitted_directions": list(res.unfitted),
            "warnings": res.warnings(split), "unseen": unseen_summary(res),
            "parameters": {form: res.seal_fits[form].values for form in FORMS},
            "profile": {"position_m": profile[0].tolist(), "exit": profile[1].tolist(),
                        "entry": profile[2].tolist(), "centre_m": centre(res)},
            "records": records}
    return {"schema": SCHEMA, "split": split,
            "metric": "on held-out moving samples: NRMSE = RMS error / range of the measured "
                      "friction; R^2; R^2 within each direction (exit v > 0, entry v < 0) and "
                      "pooled (r2_within)",
            "summary": summary_table(results), "seals": seals,
            "not_fitted": {seal or "seal": reason for seal, reason in refused.items()},
            "notes": notes + [f"not fitted: {reason}" for reason in refused.values()]
            + [f"{f'seal {res.seal}: ' if res.seal else ''}{w}"
               for res in results for w in res.warnings(split)]}


def centre(res: SealResult) -> float:
    """The records' position [m] that becomes the model's y = 0 in ``friction.yaml``: the
    middle of the positions a rig's records travel (a rig's position sensor has its own zero),
    0 for the actuator's own tests (already the model's y)."""
    rigs = [p for p in res.preps if isinstance(p.record, RigRecord)]
    if not rigs:
        return 0.0
    x = np.concatenate([p.record.x[p.train | p.test] for p in rigs])
    return float(0.5 * (x.min() + x.max())) if x.size else 0.0


def prediction_csv(res: SealResult, prep: Prepared) -> str:
    """``t,F_friction_measured,F_friction_model`` over the held-out part of a record (grid
    points in the logger's gaps left out), modelled by the selected form."""
    rec = prep.record
    model = res.model_of(res.selected, prep).predict(prep)
    first = int(np.argmax(prep.test)) if prep.test.any() else rec.t.size
    if rec.role == "holdout":
        first = 0
    rows = [f"{rec.t[k]:.4f},{prep.friction[k]:.4f},{model[k]:.4f}"
            for k in range(first, rec.t.size) if rec.valid[k]]
    return "t,F_friction_measured,F_friction_model\n" + "\n".join(rows) + "\n"


def loop_figure(res: SealResult, preps: list[Prepared]) -> Any:
    """Measured and modelled friction against velocity, against the displacement since the
    last reversal and against the position (the bore profile), one row per record (pressure),
    held-out moving samples."""
    plt = pyplot()

    fig, axes = plt.subplots(len(preps), 3, figsize=(15, 2.6 * len(preps)), squeeze=False)
    for row, prep in zip(axes, preps):
        m = prep.test
        since = since_reversal(prep.record.x, prep.v)
        label = f"{prep.record.name} ({prep.describe_pressure()})"
        row[0].plot(prep.v[m] * 1e3, prep.friction[m], ".", ms=2, color="0.6", label="measured")
        row[1].plot(since[m] * 1e3, prep.friction[m], ".", ms=2, color="0.6", label="measured")
        x = prep.record.x * 1e3
        row[2].plot(x[m], prep.friction[m], ".", ms=2, color="0.6", label="measured")
        for form, colour in {"static": "tab:blue", res.selected: "tab:red"}.items():
            model = res.model_of(form, prep).predict(prep)
            row[0].plot(prep.v[m] * 1e3, model[m], ".", ms=1.5, color=colour, label=form)
            row[1].plot(since[m] * 1e3, model[m], ".", ms=1.5, color=colour, label=form)
            row[2].plot(x[m], model[m], ".", ms=1.5, color=colour, label=form)
        if not reverses(prep):
            row[1].text(0.5, 0.5, "no reversal in this record:\npre-sliding cannot show",
                        transform=row[1].transAxes, ha="center", va="center", fontsize=9)
        row[0].set_xlabel("velocity [mm/s]")
        row[1].set_xlabel("displacement since reversal [mm] (signed as the motion)")
        row[1].set_xlim(-3, 3)
        row[2].set_xlabel("position [mm] (the record's)")
        for ax in row:
            ax.set_ylabel("friction [N]")
            ax.set_title(label, fontsize=9)
            ax.grid(alpha=0.3)
        row[1].legend(fontsize=7, markerscale=4)
    fig.tight_layout()
    return fig


def _level_axes(axes: Sequence[Any], title: str, xlabel: str) -> None:
    """Titles, labels and grids of a figure's exit and entry panels of sliding levels [N]."""
    for ax, direction in zip(axes, DIRECTIONS):
        ax.set_title(f"{direction}: {title}", fontsize=9)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("level [N]")
        ax.grid(alpha=0.3)


def pressure_figure(res: SealResult) -> Any:
    """Each record's sliding level against its gauge pressure, exit and entry side by side:
    measured, by the seal's fit and by the seal's fit made without the record, each the mean
    of the passes' levels (:func:`~jetpipe_ros.identify.drift.pass_levels`, the same statistic
    of the measured and the modelled friction, so the modelled level is at the record's own
    speed and bore positions)."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.2), squeeze=False)
    shown = {"measured": dict(marker="o", color="0.2", ls=""),
             "the seal's fit": dict(marker="s", color="tab:red", ls="", mfc="none"),
             "its fit without the record": dict(marker="D", color="tab:blue", ls="", mfc="none")}
    for prep in res.preps:
        gauge = (prep.pressure - P_ATM) * 1e-5
        levels = {"measured": pass_levels(prep),
                  "the seal's fit": pass_levels(prep, res.seal_fits[res.selected].predict(prep))}
        if prep.record.name in res.unseen_fits:
            levels["its fit without the record"] = pass_levels(
                prep, res.unseen_fits[prep.record.name].predict(prep))
        for ax, direction in zip(axes[0], DIRECTIONS):
            for label, passes in levels.items():
                level = passes[direction][1]
                if level.size:
                    ax.plot([gauge], [np.mean(level)], ms=6, label=label, **shown[label])
    _level_axes(axes[0], "sliding level of each record (mean over its passes)",
                "pressure [bar gauge]")
    for ax in axes[0]:
        ax.set_ylim(bottom=0.0)
        handles = dict(zip(*reversed(ax.get_legend_handles_labels())))
        if handles:
            ax.legend(handles.values(), handles.keys(), fontsize=7)
    fig.tight_layout()
    return fig


def _unseen_table(res: SealResult) -> str:
    """Each training record's held-out NRMSE and R^2 within direction by its own fit and by
    the seal's fit made without it, with the words on what that measures."""
    flat = res.unseen_from_one_pressure()
    rows = "".join(
        f"<tr><td>{html.escape(name)}</td>"
        f"<td>{res.scores[res.selected][name]['nrmse'] * 100:.2f} % / "
        f"{res.scores[res.selected][name]['r2_within']:.2f}</td>"
        f"<td>{u['nrmse'] * 100:.2f} % / {u['r2_within']:.2f}"
        f"{' (from one pressure: its level held)' if name in flat else ''}</td></tr>"
        for name, u in res.unseen.items())
    return ("<h3>A record the fit did not see</h3><p>Each training record judged, on the same "
            "held-out samples, by its own fit and by the seal's fit made without it (from the "
            "other records' first parts): how far the seal's planes carry to a pressure, or a "
            "repeat, that was not recorded. On the public seal records most of the gap "
            "between the two is the level, which moves from record to record beyond a line in "
            "pressure (warm-up, run-in, the order of the tests: the figure below) and which "
            "no form describes; simulate a pressure not recorded with it in mind.</p><table><tr><th>record</th><th>own fit (NRMSE / R^2 within)"
            "</th><th>fit without it</th></tr>" + rows + "</table>")


def drift_figure(preps: list[Prepared], drifts: dict[str, dict[str, Drift]]) -> Any:
    """Each pass's sliding level against time with its Theil-Sen line, exit and entry side by
    side, one colour per record."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.0), squeeze=False)
    for colour, prep in zip(plt.rcParams["axes.prop_cycle"].by_key()["color"] * 4, preps):
        for ax, direction in zip(axes[0], DIRECTIONS):
            d = drifts[prep.record.name].get(direction)
            if d is None:
                continue
            ax.plot(d.times, d.levels, "o", ms=3, color=colour,
                    label=f"{prep.record.name} {100 * d.change:+.1f} %")
            ends = np.array([d.times[0], d.times[-1]])
            ax.plot(ends, d.intercept + d.slope * ends, "-", lw=1, color=colour)
    _level_axes(axes[0], "sliding level per pass (its change over the record)",
                "time [s] (the record's)")
    for ax in axes[0]:
        if ax.lines:
            ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _drift_table(preps: list[Prepared], drifts: dict[str, dict[str, Drift]]) -> str:
    """Each record's drift per direction: the change over the record with its 95 % interval,
    in bold where the interval excludes 0."""
    def cell(d: Drift | None) -> str:
        if d is None:
            return "<td>-</td>"
        lo, hi = d.change_interval
        text = f"{d.change:+.1%} ({lo:+.1%} to {hi:+.1%}), {d.times.size} passes"
        return f"<td>{'<b>' + text + '</b>' if d.significant else text}</td>"

    rows = "".join(f"<tr><td>{html.escape(p.record.name)}</td>" +
                   "".join(cell(drifts[p.record.name].get(d)) for d in DIRECTIONS) + "</tr>"
                   for p in preps)
    return ("<h3>The level over each record</h3><p>Each pass's median friction once settled, "
            "a Theil-Sen line through the passes against time: its change over the record "
            "relative to the mean level, with the 95 % interval (bold: the interval excludes "
            "0, a drift beyond the passes' scatter). No form describes a drift: a record whose "
            "level moves meets, in its held-out "
            "part, a level its fit did not see.</p><table><tr><th>record</th>" +
            "".join(f"<th>{d}</th>" for d in DIRECTIONS) + "</tr>" + rows + "</table>")


def html_report(results: list[SealResult], doc: dict[str, Any],
                drifts: dict[str, dict[str, Drift]]) -> str:
    """The self-contained HTML report (``drifts`` as :func:`to_json` takes them)."""
    table = "".join(
        f"<tr><td>{form}</td><td>{s['median_nrmse'] * 100:.2f} %</td>"
        f"<td>{s['median_r2']:.3f}</td><td>{s['median_r2_within']:.3f}</td></tr>"
        for form, s in doc["summary"].items())
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>jetpipe friction</title>"
             "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
             "td,th{border:1px solid #ccc;padding:2px 6px;font-size:13px}</style></head><body>",
             "<h1>Seal friction from measured records</h1>",
             "<p>" + html.escape(doc["metric"]) + "</p>",
             "<h2>Held-out scores (medians over records)</h2><table><tr><th>form</th>"
             "<th>NRMSE</th><th>R^2</th><th>R^2 within direction</th></tr>" + table +
             "</table>", "<h2>In short</h2><ul>"]
    for res in results:
        nrmse = [s["nrmse"] * 100 for s in res.scores[res.selected].values()]
        drift = describe({p.record.name: drifts[p.record.name] for p in res.preps})
        held = (f"{nrmse[0]:.2f} % on its one record" if len(nrmse) == 1 else
                f"{min(nrmse):.2f}-{max(nrmse):.2f} % over {len(nrmse)} records")
        unseen = describe_unseen(res)
        parts.append(f"<li>seal {html.escape(res.seal or '(unnamed)')}: {res.selected} "
                     f"selected, held-out NRMSE {held}"
                     + (f"; {html.escape(unseen)}" if unseen else "")
                     + (f"; {html.escape(drift)}" if drift else "")
                     + "".join(f"<br><b>not used:</b> {html.escape(w)}"
                               for w in res.warnings(doc["split"])) + "</li>")
    parts += [f"<li><b>not fitted:</b> {html.escape(reason)}</li>"
              for reason in doc["not_fitted"].values()]
    parts.append("</ul>")
    for res in results:
        name = res.seal or "seal"
        parts.append(f"<h2>{html.escape(name)}: selected {res.selected}</h2><table><tr>"
                     "<th>record</th>" + "".join(f"<th>{f}</th>" for f in FORMS) + "</tr>")
        for prep in res.preps:
            cells = []
            for form in FORMS:
                s = res.scores[form].get(prep.record.name)
                cells.append(f"<td>{s['nrmse'] * 100:.2f} % / {s['r2_within']:.2f}</td>"
                             if s else "<td>-</td>")
            parts.append(f"<tr><td>{html.escape(prep.record.name)}</td>{''.join(cells)}</tr>")
        parts.append("</table><p>NRMSE / R^2 within direction, held-out moving samples.</p>")
        parts.append(_parameter_table(res.seal_fits[res.selected],
                                      list(res.per_record[res.selected].values()),
                                      res.unfitted))
        parts.append(png_img(loop_figure(res, res.preps), dpi=80))
        if res.unseen:
            parts.append(_unseen_table(res))
        if len(res.preps) > 1:
            parts.append(png_img(pressure_figure(res), dpi=80))
        if any(drifts[p.record.name] for p in res.preps):
            parts.append(_drift_table(res.preps, drifts))
            parts.append(png_img(drift_figure(res.preps, drifts), dpi=80))
    parts.append("<h2>Notes</h2><pre>" + html.escape("\n".join(doc["notes"])) + "</pre>")
    parts.append("</body></html>")
    return "".join(parts)


def _parameter_table(fit: FormFit, own: Sequence[FormFit] = (),
                     unfitted: Sequence[str] = ()) -> str:
    """The selected fit's parameters as a table with units, per direction where they are, a
    value its range's bound set marked so; with ``own`` (each record's own fit of the form,
    two or more), below each parameter that does not follow the pressure the range of its
    values over them: how consistent the seal is from record to record. A direction in
    ``unfitted`` shows no values: its planes were not fitted. The bore profile in a line
    below."""
    bounds = parameter_bounds(fit.form)

    def shown(name: str) -> str:
        value, (lo, hi, logged) = fit.values[name], bounds[name]
        if logged:
            value, lo, hi = math.log10(value), math.log10(lo), math.log10(hi)
        bound = next((b for b in (lo, hi)
                      if abs(value - b) <= _AT_BOUND * max(abs(b), _AT_BOUND * (hi - lo))), None)
        scale = _SHOWN[name.split(".")[-1]][2]
        if bound is None:
            text = f"{fit.values[name] * scale:.4g}"
        else:
            # The bound itself, within the flag's tolerance: "0", not the 1e-33 a fit stops at.
            text = f"{(10.0 ** bound if logged else bound) * scale:.4g} (at its bound)"
        if name.split(".")[-1] == "level" and fit.values[name] < 0.0:
            # A line through the records' pressures can cross 0 below the lowest of them.
            text += (f"<br><small>below 0: the line through the records' pressures, "
                     f"extrapolated; the model holds the level at {LEVEL_FLOOR:g} N or "
                     f"more</small>")
        values = [f.values[name] * scale for f in own]
        if len(values) > 1 and name.split(".")[-1] not in _WITH_PRESSURE:
            least, most = (f"{v:.3g}" if abs(v) >= 1e-9 else "0"
                           for v in (min(values), max(values)))
            text += f"<br><small>records {least} to {most}</small>"
        return text

    rows = []
    for quantity, (words, unit, _) in _SHOWN.items():
        per = [f"{d}.{quantity}" for d in DIRECTIONS]
        if all(name in fit.values for name in per):
            cells = "".join("<td><i>not fitted</i></td>" if name.split(".")[0] in unfitted
                            else f"<td>{shown(name)}</td>" for name in per)
        elif quantity in fit.values:
            cells = f"<td colspan='2'>{shown(quantity)}</td>"
        else:
            continue
        rows.append(f"<tr><td>{html.escape(words)}</td><td>{unit}</td>{cells}</tr>")
    table = ("<table><tr><th>parameter</th><th>unit</th>" +
             "".join(f"<th>{d} (v {'>' if d == 'exit' else '<'} 0)</th>" for d in DIRECTIONS) +
             "</tr>" + "".join(rows) + "</table>")
    if fit.profile.shape[1]:
        table += (f"<p>Bore profile: {fit.profile.shape[1]} knots over "
                  f"{fit.profile[0, 0] * 1e3:.1f} to {fit.profile[0, -1] * 1e3:.1f} mm of the "
                  f"records' position, factors on the level exit "
                  f"{fit.profile[1].min():.2f}-{fit.profile[1].max():.2f}, entry "
                  f"{fit.profile[2].min():.2f}-{fit.profile[2].max():.2f}.</p>")
    return table


def piston_scale(res: SealResult, base: ModelParams) -> tuple[float, str]:
    """The factor on a seal's forces from the rig's bore to the piston of ``base``, the ratio of
    their circumferences (the square root of their areas' ratio), and the words saying so;
    1 for the actuator's own friction tests (already its piston)."""
    areas = [p.record.area for p in res.preps if isinstance(p.record, RigRecord)]
    if not areas:
        return 1.0, "the actuator's own friction tests: already its piston, not scaled"
    rig = float(np.median(areas))
    scale = math.sqrt(base["chamber.piston_area"] / rig)
    return scale, (f"forces scaled by {scale:.3g} from the rig's bore "
                   f"({2e3 * math.sqrt(rig / math.pi):.1f} mm) to the piston's "
                   f"({2e3 * math.sqrt(base['chamber.piston_area'] / math.pi):.1f} mm, "
                   f"chamber.piston_area), the ratio of their circumferences")


def params_yaml(res: SealResult, base: ModelParams, to_piston: bool = False) -> str:
    """The seal's selected fit as a parameter file (ROS params layout); with ``to_piston``, its
    forces scaled to the piston of ``base`` (:func:`piston_scale`)."""
    fit = res.seal_fits[res.selected]
    shift = centre(res)
    header = (f"# jetpipe friction: seal {res.seal or '(unnamed)'}, form {res.selected}, "
              f"fitted on a friction rig (planes over the rig's pressure; see docs/friction.md)\n")
    scale, words = piston_scale(res, base) if to_piston else (1.0, "")
    header += f"# {words}\n" if words else "# forces as measured\n"
    if fit.profile.shape[1]:
        header += (f"# bore profile: the records' position {shift * 1e3:.2f} mm is the model's "
                   f"y = 0\n")
    header += "".join(f"# {d} direction: not fitted (no fitted sample moves that way): the "
                      f"starting parameters' planes\n" for d in res.unfitted)
    return header + fit.params(base, shift, scale, keep=res.unfitted).to_ros_yaml(
        only_changed=True)
