"""``jetpipe trend`` sub-command (the work is in :mod:`jetpipe_ros.twin.trend`)."""

from __future__ import annotations

import argparse

#: Significance bar of a drift, in standard errors of its slope (the diagnosis' MIN_T; a
#: test checks they agree): here so that ``jetpipe --help`` imports nothing heavy.
MIN_T = 3.0


def _run(args: argparse.Namespace) -> int:
    from jetpipe_ros.fileio import output_dir, to_json, write_files
    from jetpipe_ros.twin.trend import TrendError, find_diagnoses, plot, read_point, table, trend

    out = output_dir(args.out, "--out")
    points = [read_point(p) for p in find_diagnoses(args.dirs)]
    if len(points) < 2:
        raise TrendError(f"{', '.join(args.dirs)}: one diagnosis; a trend needs two or more")
    points.sort(key=lambda p: p.date)
    series = trend(points)
    text = table(series)
    doc = {"schema": "jetpipe.trend/1",
           "diagnoses": [{"path": str(p.path), "date": p.date.isoformat(),
                          "date_from": p.source, "effect": p.effect} for p in points],
           "min_t": MIN_T, "series": [s.to_json() for s in series],
           "drifts": [s.name for s in series if s.drift]}
    write_files({out / "trend.json": to_json(doc), out / "trend.txt": text + "\n",
                 out / "trend.png": plot(series, points[0].date)})
    for p in points:
        print(f"{p.date:%Y-%m-%d %H:%M} ({p.source}) {p.effect:18s} {p.path}")
    print(text)
    drifts = [s for s in series if s.drift]
    print(f"{len(drifts)} drift(s): " + ", ".join(
        f"{s.name} {s.slope:+.3g} +- {s.stderr:.2g} per day" for s in drifts) if drifts else
        "no drift")
    print(f"table, plot: {out}/trend.txt, {out}/trend.png, {out}/trend.json")
    return 0


def add_command(subparsers) -> None:
    """Register ``trend``."""
    p = subparsers.add_parser(
        "trend", help="calibration knobs and effect parameters of diagnoses over time; drifts",
        description="Read the diagnoses (diagnosis.json) in or below each DIR, date each (a "
                    "'date' field, else a date in its folder's name, else the file's time), "
                    "and write a table and a plot of the calibration knobs and the effect "
                    "parameters against time, flagging a steady drift (slope at least "
                    f"{MIN_T:g} standard errors) with its rate and uncertainty.")
    p.add_argument("dirs", metavar="DIR", nargs="+", help="folder holding diagnoses")
    p.add_argument("--out", required=True, metavar="OUT_DIR",
                   help="where trend.txt, trend.png and trend.json go")
    p.set_defaults(func=_run)
