"""``jetpipe friction DIR --out OUT``: seal friction from friction-rig records.

Every output (``friction.yaml``, ``friction.json``, ``report.html``, ``prediction/*.csv``) is
written together at the end: all or, on an error, none.
"""

from __future__ import annotations


def _run(args) -> int:
    from jetpipe_ros import fileio
    from jetpipe_ros.dataset import DatasetError, read_records
    from jetpipe_ros.identify.seal import identify_seal
    from jetpipe_ros.identify.seal_report import (html_report, params_yaml, prediction_csv,
                                                  to_json)
    from jetpipe_ros.model import ModelParams, load_params

    out = fileio.output_dir(args.out, "--out")
    if not 0.05 <= args.split <= 0.95:
        raise DatasetError(f"--split: {args.split:g} must lie in [0.05, 0.95]")
    base = load_params(args.params) if args.params else ModelParams()
    records = read_records(args.dir)
    seals: dict[str, list] = {}
    for rec in records:
        seals.setdefault(rec.seal, []).append(rec)
    notes = [n for rec in records for n in rec.notes]
    results = [identify_seal(seal, recs, args.split) for seal, recs in seals.items()]
    doc = to_json(results, args.split, notes)
    files: dict = {out / "friction.yaml": params_yaml(results[0], base),
                   out / "friction.json": fileio.to_json(doc) + "\n",
                   out / "report.html": html_report(results, doc)}
    if len(results) > 1:
        for res in results:
            files[out / f"friction-{res.seal or 'seal'}.yaml"] = params_yaml(res, base)
    for res in results:
        for prep in res.preps:
            files[out / "prediction" / f"{prep.record.name}.csv"] = prediction_csv(res, prep)
    fileio.write_files(files)
    for form, s in doc["summary"].items():
        print(f"{form:16s} held-out median NRMSE {s['median_nrmse'] * 100:5.2f} %  "
              f"R^2 within direction {s['median_r2_within']:5.2f}")
    for res in results:
        print(f"seal {res.seal or '(unnamed)'}: selected {res.selected}")
    print(f"parameters -> {out / 'friction.yaml'}\nscores -> {out / 'friction.json'}\n"
          f"report -> {out / 'report.html'}")
    return 0


def add_command(subparsers) -> None:
    """``jetpipe friction``: fit and select seal friction models on friction-rig records."""
    cmd = subparsers.add_parser(
        "friction", help="seal friction from friction-rig records (t,x,p,F)",
        description="Fit the model's friction forms (Coulomb + viscous, the static planes, "
                    "LuGre, Maxwell-slip) to friction-rig records (records.yaml + CSVs "
                    "t,x,p,F) on the first part of each record, judge them on the rest, select "
                    "the best by held-out NRMSE and write OUT/friction.yaml (loadable by "
                    "jetpipe simulate and actuator_sim), OUT/friction.json, OUT/report.html "
                    "and OUT/prediction/<record>.csv.")
    cmd.add_argument("dir", help="friction-rig folder (records.yaml + CSVs; docs/friction.md)")
    cmd.add_argument("--out", required=True, help="output directory")
    cmd.add_argument("--params", help="parameters the fitted friction is written into (YAML); "
                                      "default: the nominal model")
    cmd.add_argument("--split", type=float, default=0.5,
                     help="fraction of each record fitted; the rest is judged (default 0.5)")
    cmd.set_defaults(func=_run)
