"""``jetpipe diagnose DIR1 DIR2 ... --out OUT``: one diagnosis per actuator's dataset, and a
summary of the fleet a maintenance engineer reads at a glance.

Each dataset is diagnosed into ``OUT/<dataset folder name>/`` (diagnosis.json, report.html,
augmented.yaml, as for one dataset), one diagnosis per task on the workers of a Dask cluster
(:class:`cluster.Cluster`; its candidate fits then run one after the other inside that worker),
or one after the other in this process without a cluster. ``OUT/fleet.json`` and
``OUT/fleet.html`` then hold a row per actuator, sorted by the held-out gap of the nominal model
(largest first; failed datasets last): the verdict, the recalibration and the held-out gap
before and after. A dataset that fails (missing, malformed, or any error in its diagnosis) gets
its error in its row; the others still finish. Workers read the datasets and write the outputs
under the paths given here, so a remote cluster needs them on a shared file system.
"""

from __future__ import annotations

import glob
import html
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from distributed import as_completed

from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.workflows.cluster import Cluster
from jetpipe_ros.workflows.diagnose import OUTPUTS, diagnose
from jetpipe_ros.fileio import to_json, write_files
from jetpipe_ros.model import ModelParams, ParameterError

SCHEMA = "jetpipe.fleet/1"
OUTPUTS_FLEET = ("fleet.json", "fleet.html")
#: A calibration knob counts as off when its factor against nominal is off by this much.
KNOB_OFF = 0.05
#: Verdict colours of the fleet figure; effects not listed take the next of :data:`PALETTE`.
VERDICT_COLORS = {"none": "#2ca02c", "unlisted": "#444444"}
PALETTE = ("#1f77b4", "#ff7f0e", "#9467bd", "#d62728", "#8c564b", "#e377c2", "#17becf",
           "#bcbd22", "#aec7e8", "#ffbb78")


def dataset_dirs(arguments: Sequence[str]) -> tuple[list[Path], bool]:
    """The dataset directories named by the command line, and whether they make a fleet.

    An argument with glob characters that names no existing path is expanded (sorted, only
    directories kept); a glob that matches no directory is an error. More than one dataset, or
    any glob, makes a fleet; a single plain directory is diagnosed as before.
    """
    dirs: list[Path] = []
    globbed = False
    for arg in arguments:
        if glob.has_magic(arg) and not Path(arg).exists():
            globbed = True
            matches = [Path(m) for m in sorted(glob.glob(arg)) if Path(m).is_dir()]
            if not matches:
                raise DatasetError(f"{arg}: matches no dataset directory")
            dirs += matches
        else:
            dirs.append(Path(arg))
    return dirs, globbed or len(dirs) > 1


def names_of(dirs: Sequence[Path]) -> list[str]:
    """Each dataset's folder name, the name of its actuator and of its output folder; two
    datasets of one name are refused."""
    seen: dict[str, Path] = {}
    for d in dirs:
        name = d.resolve().name
        if name in seen:
            raise DatasetError(f"two datasets named {name}: {seen[name]} and {d} (each gets "
                               f"OUT/{name}/: rename one folder)")
        seen[name] = d
    return list(seen)


def diagnose_one(dataset: str, out: str, params: ModelParams | None) -> dict:
    """Diagnose one dataset into ``out`` (fits in this process); its fleet row. Any error is
    caught into the row, and outputs an earlier run left in ``out`` are removed, so that the
    folder never shows a diagnosis this run did not make."""
    t0 = time.perf_counter()
    name = Path(out).name
    try:
        result = diagnose(dataset, out, params, workers=1, quiet=True)
    except Exception as exc:  # the dataset's failure, reported in its row  # noqa: BLE001
        for stale in OUTPUTS:
            Path(out, stale).unlink(missing_ok=True)
        return failed_row(name, dataset, exc, time.perf_counter() - t0)
    return row(name, dataset, result, time.perf_counter() - t0)


def failed_row(name: str, dataset: str, exc: BaseException, seconds: float) -> dict:
    """The row of a dataset whose diagnosis failed: its error in one line."""
    plain = isinstance(exc, (DatasetError, ParameterError))
    message = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return {"name": name, "dataset": dataset, "status": "failed",
            "error": message if plain else f"{type(exc).__name__}: {message}".rstrip(": "),
            "seconds": seconds}


def row(name: str, dataset: str, result: dict, seconds: float) -> dict:
    """The fleet row of one diagnosis (diagnosis.json's ``result``)."""
    v, cal, gap = result["verdict"], result["calibration"], result["gap"]
    return {
        "name": name, "dataset": dataset, "status": "ok", "error": None,
        "outputs": {k: f"{name}/{k}" for k in OUTPUTS},
        "verdict": {"effect": v["effect"], "effects": v["effects"],
                    "subsystem": v["subsystem"], "confidence": v["confidence"],
                    "params": v["params"], "reason": v["reason"]},
        "calibration": {"significant": cal["significant"], "knobs": cal["knobs"],
                        "off": {k: f for k, f in cal["knobs"].items()
                                if abs(f - 1.0) > KNOB_OFF},
                        "summary": cal["summary"], "gap_before": cal["gap_before"],
                        "gap_after": cal["gap_after"]},
        "gap": {"metric": gap["metric"], "nominal": gap["nominal"],
                "recalibrated": gap["recalibrated"], "augmented": gap["augmented"],
                "shrinkage": gap["shrinkage"]},
        "seconds": seconds,
    }


def run_fleet(dirs: Sequence[Path], out_dir: str | Path, params: ModelParams | None = None,
              workers: int = 2, scheduler: str | None = None,
              progress: Callable[[str], None] = print) -> dict:
    """Diagnose every dataset of ``dirs`` into ``out_dir/<name>/`` and write ``fleet.json`` and
    ``fleet.html`` there; return fleet.json's content. ``workers``/``scheduler``: where the
    diagnoses run (:class:`Cluster`; one diagnosis per task)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ParameterError(f"--out {out_dir}: exists and is not a directory")
    names = names_of(dirs)
    tasks = [(str(d.resolve()), str((out_dir / n).resolve())) for d, n in zip(dirs, names)]
    out_dir.mkdir(parents=True, exist_ok=True)
    began = time.perf_counter()
    rows: list[dict] = []

    def report(r: dict) -> None:
        rows.append(r)
        if r["status"] == "ok":
            v, g = r["verdict"], r["gap"]
            what = (f"{v['effect']} (confidence {v['confidence']:.2f}), held-out gap "
                    f"{g['nominal']:.2f} % -> {g['augmented']:.2f} %")
        else:
            what = f"FAILED: {r['error']}"
        progress(f"[{len(rows)}/{len(tasks)}] {r['name']}: {what} ({r['seconds']:.0f} s; "
                 f"{time.perf_counter() - began:.0f} s elapsed)")

    with Cluster(workers, scheduler) as cluster:
        progress(f"diagnosing {len(tasks)} datasets into {out_dir} on {cluster}")
        client = cluster.client
        if client is None:
            for dataset, out in tasks:
                report(diagnose_one(dataset, out, params))
        else:
            futures = [client.submit(diagnose_one, dataset, out, params, pure=False)
                       for dataset, out in tasks]
            task_of = {f.key: t for f, t in zip(futures, tasks)}
            for fut in as_completed(futures):
                try:
                    report(fut.result())
                except Exception as exc:  # the worker died (KilledWorker, ...)  # noqa: BLE001
                    dataset, out = task_of[fut.key]
                    report(failed_row(Path(out).name, dataset, exc, 0.0))
    fleet = summary(rows, time.perf_counter() - began, str(cluster))
    write(out_dir, fleet)
    return fleet


def summary(rows: Sequence[dict], seconds: float, where: str) -> dict:
    """fleet.json: the rows sorted by the nominal model's held-out gap, failures last."""
    ok = sorted((r for r in rows if r["status"] == "ok"), key=lambda r: -r["gap"]["nominal"])
    failed = sorted((r for r in rows if r["status"] != "ok"), key=lambda r: r["name"])
    metric = ok[0]["gap"]["metric"] if ok else None
    return {"schema": SCHEMA, "datasets": len(rows), "succeeded": len(ok),
            "failed": len(failed), "metric": metric,
            "sorted_by": "gap.nominal (held-out gap of the nominal model), largest first; "
                         "failed datasets last",
            "knob_off_threshold": KNOB_OFF, "seconds": seconds, "ran_on": where,
            "actuators": [*ok, *failed]}


def write(out_dir: Path, fleet: dict) -> None:
    """Write fleet.json and fleet.html to ``out_dir``, both complete or neither replaced."""
    write_files({out_dir / "fleet.json": to_json(fleet) + "\n",
                 out_dir / "fleet.html": render(fleet)})


def _colors(rows: Sequence[dict]) -> dict[str, str]:
    """A colour per verdict effect."""
    colors = dict(VERDICT_COLORS)
    rest = iter(PALETTE)
    for r in rows:
        colors.setdefault(r["verdict"]["effect"], next(rest, "#999999"))
    return colors


def figure(fleet: dict) -> str:
    """The fleet at a glance, inlined as PNG: per actuator (rows as in the table), the held-out
    gap of the nominal model (pale) and of the augmented model (full colour), coloured by
    verdict; beside it, the calibration knobs as factors against nominal where the
    recalibration is significant, those off by more than :data:`KNOB_OFF` labelled."""
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.patches import Patch

    from jetpipe_ros.figures import png_img, pyplot

    plt = pyplot()
    rows = fleet["actuators"]
    ok = [r for r in rows if r["status"] == "ok"]
    knobs = list(ok[0]["calibration"]["knobs"]) if ok else []
    n = len(rows)
    fig, (ax, kx) = plt.subplots(1, 2, figsize=(13, 0.42 * n + 2.0), sharey=True,
                                 gridspec_kw={"width_ratios": [1.2, 1.0]})
    colors = _colors(ok)
    y = list(range(n))[::-1]  # first row on top
    top = max([r["gap"]["nominal"] for r in ok] or [1.0])
    for yi, r in zip(y, rows):
        if r["status"] != "ok":
            ax.text(0.01 * top, yi, f"failed: {r['error'][:70]}", va="center", fontsize=8,
                    color="#d62728")
            continue
        c = colors[r["verdict"]["effect"]]
        ax.barh(yi + 0.2, r["gap"]["nominal"], 0.38, color=c, alpha=0.35)
        ax.barh(yi - 0.2, r["gap"]["augmented"], 0.38, color=c)
        ax.text(r["gap"]["nominal"], yi + 0.2, f" {r['gap']['nominal']:.2f}", va="center",
                fontsize=7)
        ax.text(r["gap"]["augmented"], yi - 0.2, f" {r['gap']['augmented']:.2f}",
                va="center", fontsize=7)
    ax.set_yticks(y, [r["name"] for r in rows])
    ax.set_xlim(0, 1.2 * top)
    ax.set_xlabel(f"held-out gap [%] ({fleet['metric'] or 'no diagnosis'}): pale nominal, "
                  "full augmented")
    ax.legend(handles=[Patch(color=c, label=e) for e, c in colors.items()
                       if any(r["verdict"]["effect"] == e for r in ok)],
              title="verdict", fontsize=8, loc="lower right")
    ax.grid(axis="x", alpha=0.3)
    grid = [[r["calibration"]["knobs"].get(k, 1.0) if r["status"] == "ok" and
             r["calibration"]["significant"] else float("nan") for k in knobs] for r in rows]
    if knobs:
        im = kx.imshow(grid[::-1], aspect="auto", cmap="RdBu_r", origin="lower",
                       norm=TwoSlopeNorm(1.0, 0.5, 1.5), extent=(-0.5, len(knobs) - 0.5,
                                                                 -0.5, n - 0.5))
        for yi, r, vals in zip(y, rows, grid):
            if r["status"] != "ok":
                continue
            if not r["calibration"]["significant"]:
                kx.text(len(knobs) / 2 - 0.5, yi, "recalibration not significant",
                        ha="center", va="center", fontsize=8, color="#777777")
                continue
            for j, f in enumerate(vals):
                if abs(f - 1.0) > KNOB_OFF:
                    kx.text(j, yi, f"{f:.2f}", ha="center", va="center", fontsize=7)
        kx.set_xticks(range(len(knobs)), knobs, rotation=45, ha="right", fontsize=8)
        fig.colorbar(im, ax=kx, label="factor against nominal", shrink=0.8)
    kx.set_title(f"calibration knobs (labelled: off by more than {100 * KNOB_OFF:.0f} %)",
                 fontsize=9)
    fig.tight_layout()
    return png_img(fig)


def render(fleet: dict) -> str:
    """fleet.html: a self-contained page (figure inlined), the table of actuators."""
    e = html.escape
    rows = fleet["actuators"]
    head = (f"{fleet['datasets']} actuators: {fleet['succeeded']} diagnosed, "
            f"{fleet['failed']} failed; sorted by the nominal model's held-out gap "
            f"({e(str(fleet['metric']))}, %), largest first; failed datasets last. "
            f"{fleet['seconds']:.0f} s on {e(fleet['ran_on'])}.")
    table = ["<table><tr><th>actuator</th><th>verdict</th><th>subsystem</th>"
             "<th>confidence</th><th>recalibration</th><th>knobs off by more than "
             f"{100 * KNOB_OFF:.0f} %</th><th>held-out gap nominal</th><th>recalibrated</th>"
             "<th>augmented</th><th>shrinkage</th><th>report</th></tr>"]
    for r in rows:
        if r["status"] != "ok":
            table.append(f"<tr class='failed'><td>{e(r['name'])}</td><td colspan='10'>"
                         f"failed: {e(r['error'])}<br><small>{e(r['dataset'])}</small>"
                         f"</td></tr>")
            continue
        v, c, g = r["verdict"], r["calibration"], r["gap"]
        cal = ("significant: " + e("; ".join(c["summary"])) if c["significant"]
               else "not significant")
        off = (", ".join(f"{e(k)} {f:.2f}" for k, f in c["off"].items()) or "none"
               if c["significant"] else "(recalibration not kept)")
        table.append(
            f"<tr><td>{e(r['name'])}</td><td><b>{e(v['effect'])}</b></td>"
            f"<td>{e(v['subsystem'])}</td><td>{v['confidence']:.2f}</td><td>{cal}</td>"
            f"<td>{off}</td><td>{g['nominal']:.2f} %</td><td>{g['recalibrated']:.2f} %</td>"
            f"<td>{g['augmented']:.2f} %</td><td>{100 * g['shrinkage']:.0f} %</td>"
            f"<td><a href='{e(r['outputs']['report.html'])}'>report</a></td></tr>")
    table.append("</table>")
    style = ("body{font-family:sans-serif;margin:2em;max-width:1400px}"
             "table{border-collapse:collapse;font-size:90%}td,th{border:1px solid #ccc;"
             "padding:3px 6px;vertical-align:top}tr.failed td{background:#fde0e0}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>jetpipe fleet "
            f"diagnosis</title><style>{style}</style></head><body><h1>Fleet diagnosis</h1>"
            f"<p>{head}</p>{figure(fleet)}<h2>Actuators</h2>{''.join(table)}"
            "<p>Recalibration: the nominal parameters refitted per actuator (factors against "
            "nominal); knobs are shown where the recalibration is significant, i.e. kept in "
            "the augmented model. Held-out gap: the model's prediction error on the held-out "
            "experiments beyond sensor noise.</p></body></html>")
