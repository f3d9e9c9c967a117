"""What ``jetpipe identify`` tells a person: a text summary with each fit error next to the
paper's figure, and a self-contained HTML page with the plots (flow map, valve Bode, hysteresis
loop, friction planes, replays)."""

from __future__ import annotations

import html
from typing import Any

import numpy as np

from jetpipe_ros.figures import png_img, pyplot
from jetpipe_ros.identify.friction import DETERMINED, QUANTITIES, paper_planes, undetermined
from jetpipe_ros.identify.identify import Identification
from jetpipe_ros.identify.valve import peak, response
from jetpipe_ros.model.actuator import flow_map
from jetpipe_ros.model.flow import N_TERMS, TABLE_P, TABLE_U, mass_flow
from jetpipe_ros.model.friction import plane
from jetpipe_ros.model.params import FLOW_COEFFICIENTS, FRICTION_UNITS
from jetpipe_ros.model.valve import jetpipe_position

#: The paper's figures the summary compares with.
PAPER = {"flow_max_error": 0.0005, "resonance_hz": 49.0, "hysteresis_v": 0.25,
         "plane_error": 0.05}


def summary(ident: Identification) -> str:
    """Plain-text summary: per procedure, what was used, what was found, the paper's figure."""
    rates = sorted({round(1.0 / r.experiment.dt) for r in ident.recordings})
    lines = ["jetpipe identify: " + ", ".join(
        f"{k}: {sum(r.kind == k for r in ident.recordings)}"
        for k in ("charge", "sweep", "ramp", "friction", "validation")) + " experiment(s), "
        f"logged at {' and '.join(f'{hz:g}' for hz in rates)} Hz"]
    lines += [f"- {note}" for note in ident.notes]
    for name, why in ident.skipped.items():
        lines.append(f"- {name}: SKIPPED, starting values kept: {why}")
    if ident.flow is not None:
        f = ident.flow
        (u0, u1), (p0, p1) = f.u_range(), f.p_range()
        lines.append(f"- flow map (Eq. 8) from {len(f.experiments)} charge/discharge test(s), "
                     f"{len(f.levels)} voltage levels, u_eq {u0:.2f}..{u1:.2f} V, p "
                     f"{p0:.2f}..{p1:.2f} bar: fit error max {f.max_error:.2e} kg/s, rms "
                     f"{f.rms_error:.2e} kg/s (paper: max about {PAPER['flow_max_error']} kg/s)")
    if ident.table is not None:
        f = ident.table
        verdict = (f"kept (largest correction {max(map(abs, f.table)):.2f} g/s)" if f.kept else
                   "not kept: Eq. 8 with the bench's own scales predicts the tests left out as "
                   "well (table zero)")
        lines.append(f"- flow map correction table from {len(f.experiments)} charge/discharge "
                     f"test(s), each left out in turn: Eq. 8's error on them rms "
                     f"{f.rms_before:.2e} kg/s, with the table {f.rms_after:.2e} kg/s; with the "
                     f"bench's own scales (each chamber's flow per direction, the jet pipe's "
                     f"gain) {f.rms_scales:.2e} kg/s, with the table beside them "
                     f"{f.rms_scales_table:.2e} kg/s: {verdict}")
    if ident.valve is not None:
        v = ident.valve
        fr, g = peak(ident.params)
        fr0, g0 = peak(ident.base)
        lines.append(
            f"- valve (Eq. 4, 9, 10) from {', '.join(v.experiments)} (up to "
            f"{v.top_frequency:.0f} Hz): K_b {v.values['valve.back_emf_constant']:.4g} V s/rad, "
            f"delay {v.values['valve.delay'] * 1e3:.2f} ms, lead-lag zero "
            f"{v.values['valve.lag_zero']:.0f} / pole {v.values['valve.lag_pole']:.0f} rad/s "
            f"(paper: 0.1, 2 ms, 220 / 155), which trade against each other; the response "
            f"they give, which the sweep pins: resonance {fr:.1f} Hz, peak gain {g:.3f} "
            f"(starting model {fr0:.1f} Hz, {g0:.3f}; paper measured about "
            f"{PAPER['resonance_hz']:.0f} Hz); residual {v.rms_error:.0f} Pa rms as pressure")
    if ident.hysteresis is not None:
        h = ident.hysteresis
        verdict = ("valve_hysteresis effect switched on" if h.significant
                   else "below resolution, left off")
        lines.append(f"- hysteresis (Sec. 2.2) from {', '.join(h.experiments)}: half-width "
                     f"{h.half_width:.3f} V median, {h.max_half_width:.3f} V max (paper: "
                     f"{PAPER['hysteresis_v']} V); midpoint line u = {h.midline_slope:.3f} u_eq "
                     f"{h.midline_offset:+.3f} V (model: u = u_eq); {verdict}")
    if ident.friction is not None:
        fr_res = ident.friction
        for phase, errors in fr_res.max_relative_error.items():
            tests = [t for t in fr_res.tests if t.phase == phase]
            errs = ", ".join(f"{q} {100 * e:.1f} %" if np.isfinite(e) else f"{q} not judged"
                             for q, e in errors.items())
            eq = "20-23" if phase == "entry" else "24-27"
            lines.append(f"- friction {phase} planes (Eq. {eq}) from {len(tests)} test(s): plane "
                         f"max relative error {errs} (paper: < 5 %)")
            weak = {q: [t.name for t in tests if undetermined(t, q)] for q in QUANTITIES}
            if any(weak.values()):
                lines.append(f"  note: not judged where a test cannot place the value within "
                             f"{100 * DETERMINED:.0f} % (its standard error; the plane weighs "
                             f"each test by it): " + "; ".join(
                                 f"{q} in {', '.join(names)}" for q, names in weak.items()
                                 if names))
        for note in fr_res.skipped:
            lines.append(f"  note: {note}")
    for rp in ident.replays:
        if rp.kind == "validation":
            lines.append(f"- replay of held-out {rp.name}: position rms "
                         f"{rp.rms_position['identified'] * 1e3:.3f} mm identified vs "
                         f"{rp.rms_position['starting'] * 1e3:.3f} mm starting; pressure rms "
                         f"{rp.rms_pressure['identified'] / 1e5:.4f} vs "
                         f"{rp.rms_pressure['starting'] / 1e5:.4f} bar")
    fric = [rp for rp in ident.replays if rp.kind == "friction"]
    if fric:
        worst = max(fric, key=lambda rp: rp.rms_position["identified"])
        lines.append(f"- friction check (Fig. 28): {len(fric)} test trajectories replayed on the "
                     f"regulated rig, worst position rms "
                     f"{worst.rms_position['identified'] * 1e3:.3f} mm ({worst.name})")
    return "\n".join(lines)


def table_figure(ident: Identification, plt: Any) -> str:
    """The correction table over voltage and pressure, with where the samples lie."""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    values = np.array(ident.table.table).reshape(TABLE_U.size, TABLE_P.size)
    top = max(float(np.abs(values).max()), 1e-9)
    image = ax.pcolormesh(TABLE_P, TABLE_U, values, shading="gouraud", cmap="RdBu_r",
                          vmin=-top, vmax=top)
    fig.colorbar(image, ax=ax, label="correction to Eq. 8 [g/s]")
    s = ident.table.samples
    ax.plot(s.p_bar[::40], s.u[::40], "k.", ms=1)
    ax.set(xlabel="chamber pressure [bar]", ylabel="equivalent voltage u_eq [V]",
           title="Flow map correction table (colour) and the samples it was fitted to (dots)")
    return png_img(fig)


def figures(ident: Identification) -> list[tuple[str, str]]:
    """(title, <img> tag) of each plot the results allow."""
    plt = pyplot()

    out = []
    if ident.flow is not None:
        s = ident.flow.samples
        identified = flow_map(ident.params)
        what = "Eq. 8 with its table" if identified.size > N_TERMS else "Eq. 8"
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for level in ident.flow.levels:
            m = np.isclose(s.u, level, atol=5e-4)
            if not m.any():
                continue
            p = np.linspace(s.p_bar[m].min(), s.p_bar[m].max(), 50)
            line, = ax.plot(p, mass_flow(identified, np.full(50, level), p) * 1e3,
                            label=f"{level:g} V")
            ax.plot(s.p_bar[m][::20], s.q[m][::20] * 1e3, ".", ms=2, color=line.get_color())
            ax.plot(p, mass_flow(FLOW_COEFFICIENTS, np.full(50, level), p) * 1e3, ":",
                    color=line.get_color())
        ax.set(xlabel="chamber pressure [bar]", ylabel="mass flow [g/s]",
               title=f"Flow map: samples (dots), identified {what} (lines), paper (dotted)")
        ax.legend(fontsize=7, ncol=2)
        out.append(("Mass flow map (Sec. 2.3)", png_img(fig)))
    if ident.table is not None and ident.table.kept:
        out.append(("Flow map correction table", table_figure(ident, plt)))
    if ident.valve is not None:
        v = ident.valve
        f = np.linspace(1.0, max(v.top_frequency, 70.0), 400)
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        a1.plot(v.frequency, np.abs(v.measured), ".", ms=3, label="measured (1 Hz bands)")
        a2.plot(v.frequency, np.degrees(np.angle(v.measured)), ".", ms=3)
        for label, p, style in (("identified", ident.params, "-"), ("starting", ident.base, ":")):
            h = response(p, f, v.sample_time)
            a1.plot(f, np.abs(h), style, label=label)
            a2.plot(f, np.degrees(np.angle(h)), style)
        # The bands show the valve through the sweep's end (its last cycles still ringing),
        # the derivative's window and the samples' aliasing: the identified chain is drawn as
        # the record shows it too, like for like with the dots (at 1 kHz 3 % apart from the
        # chain itself at 50 Hz, 13 % at 70 Hz; at 200 Hz 21 % and 64 %).
        a1.plot(v.frequency, np.abs(v.seen), "-", lw=0.8, color="0.4",
                label=f"identified, as the {1.0 / v.sample_time:g} Hz record shows it")
        a2.plot(v.frequency, np.degrees(np.angle(v.seen)), "-", lw=0.8, color="0.4")
        a1.set(ylabel="gain u -> u_eq [V/V]", title="Valve frequency response (locked sweep)")
        a2.set(xlabel="frequency [Hz]", ylabel="phase [deg]")
        a1.legend(fontsize=8)
        out.append(("Valve dynamics (Sec. 2.1, 2.4)", png_img(fig)))
    if ident.hysteresis is not None:
        h = ident.hysteresis
        fig, ax = plt.subplots(figsize=(6, 5))
        x = jetpipe_position(h.u_eq) * 1e3
        ax.plot(h.u[h.rising][::10], x[h.rising][::10], ".", ms=2, label="rising")
        ax.plot(h.u[~h.rising][::10], x[~h.rising][::10], ".", ms=2, label="falling")
        ax.plot(0.5 * (h.u_rise + h.u_fall), jetpipe_position(h.levels) * 1e3, "k-",
                label="midpoint line")
        ax.set(xlabel="command u [V]", ylabel="jet-pipe position [mm] (from u_eq, Eq. 5)",
               title=f"Hysteresis loop: half-width {h.half_width:.3f} V")
        ax.legend(fontsize=8)
        out.append(("Hysteresis (Sec. 2.2)", png_img(fig)))
    if ident.friction is not None and ident.friction.tests:
        fr = ident.friction
        fig, axes = plt.subplots(1, 4, figsize=(14, 3.6))
        for ax, q in zip(axes, QUANTITIES):
            for phase, mark in (("entry", "o"), ("exit", "s")):
                tests = [t for t in fr.tests if t.phase == phase]
                if not tests or phase not in fr.planes:
                    continue
                meas = np.array([t.values[q] for t in tests])
                # A test's standard error, capped at its value: one that cannot place it
                # at all would otherwise stretch the axis over nothing.
                se = np.minimum([t.errors.get(q, 0.0) for t in tests], np.abs(meas))
                for label, c, col in (("identified plane", fr.planes[phase][q], "C0"),
                                      ("paper plane", paper_planes(phase)[q], "C3")):
                    pred = np.array([plane(np.asarray(c), t.p1_bar, t.p2_bar)
                                     for t in tests])
                    ax.errorbar(meas, pred, xerr=se if col == "C0" else None, fmt=mark, ms=4,
                                mfc="none" if col == "C3" else col, color=col, elinewidth=0.8,
                                label=f"{phase}, {label}")
            lim = ax.get_xlim()
            ax.plot(lim, lim, "k:", lw=0.8)
            ax.set(xlabel=f"per-test {q} [{FRICTION_UNITS[q]}]", ylabel="plane value")
        axes[0].legend(fontsize=6)
        fig.suptitle("Friction planes (Eq. 20-27) against the per-test values (bars: each "
                     "test's standard error)")
        out.append(("Friction (Sec. 4.2)", png_img(fig)))
    shown = [rp for rp in ident.replays if rp.kind == "validation"][:2]
    fric = [rp for rp in ident.replays if rp.kind == "friction"][:1]
    for rp in shown + fric:
        fig, ax = plt.subplots(figsize=(8, 3.5))
        ax.plot(rp.t, rp.measured * 1e3, lw=1, label="measured")
        for label, y in rp.simulated.items():
            ax.plot(rp.t, y * 1e3, lw=1, ls="--" if label == "starting" else "-", label=label)
        ax.set(xlabel="time [s]", ylabel="position [mm]", title=f"Replay of {rp.name}")
        ax.legend(fontsize=8)
        out.append((f"Replay: {rp.name}", png_img(fig)))
    return out


def html_report(ident: Identification) -> str:
    """The self-contained HTML report."""
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(_fmt(v))}</td>"
                   f"<td>{html.escape(_fmt(ident.base[k]))}</td></tr>"
                   for k, v in ident.changes().items())
    figs = "".join(f"<h2>{html.escape(t)}</h2>{img}" for t, img in figures(ident))
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>jetpipe identify</title>"
            "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
            "td,th{border:1px solid #ccc;padding:2px 6px;font-size:13px}"
            "pre{white-space:pre-wrap}</style></head><body>"
            "<h1>Parameter identification</h1><pre>" + html.escape(summary(ident)) + "</pre>"
            "<h2>Identified parameters</h2><table><tr><th>parameter</th><th>identified</th>"
            "<th>starting</th></tr>" + rows + "</table>" + figs + "</body></html>")


#: Lists longer than this (the flow map's correction table) are summarised, not listed.
LONGEST_LISTED = 24


def _fmt(value: Any) -> str:
    if isinstance(value, list) and len(value) > LONGEST_LISTED:
        return (f"{len(value)} values from {min(value):.4g} to {max(value):.4g}" if any(value)
                else f"{len(value)} zeros")
    if isinstance(value, list):
        return "[" + ", ".join(f"{x:.5g}" for x in value) + "]"
    return f"{value:.5g}" if isinstance(value, float) else str(value)


