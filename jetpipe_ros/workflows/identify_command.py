"""``jetpipe identify DATASET_DIR --out params.yaml``: the paper's procedures on a dataset.

Before any procedure runs the record's signs are read as the diagnosis reads them
(:mod:`jetpipe_ros.diagnosis.signs`): a command, position or pressures counted the other way
would otherwise be identified as they are logged (a command counted the other way as a
mirrored flow map, a position as friction of the wrong sign), and the parameters would describe
no actuator of the data contract. A record read otherwise than logged is said on the console,
in the parameter file's header and in the report.

Both outputs (the parameter YAML and the HTML report) are checked before the work and written
together at the end: both or, on an error, neither.
"""

from __future__ import annotations


def _run(args) -> int:
    from jetpipe_ros import fileio
    from jetpipe_ros.dataset import COMPLETE, DatasetError, read_dataset
    from jetpipe_ros.diagnosis.signs import rewritten
    from jetpipe_ros.identify.identify import PROCEDURES, identify
    from jetpipe_ros.identify.report import html_report, summary
    from jetpipe_ros.model import ModelParams, load_params
    from jetpipe_ros.model.limits import Limits

    out = fileio.output_file(args.out, "--out")
    report = fileio.output_file(args.report if args.report is not None
                                else out.with_suffix(".report.html"), "--report")
    if out.resolve() == report.resolve():
        raise fileio.FileError(f"--report: {report} is also --out; give another file")
    base = load_params(args.params) if args.params else ModelParams()
    if args.procedures:
        chosen = [p.strip() for p in args.procedures.split(",") if p.strip()]
        unknown = [p for p in chosen if p not in PROCEDURES]
        if unknown:
            raise DatasetError(f"--procedures: unknown {', '.join(unknown)}; known: "
                               f"{', '.join(PROCEDURES)}")
        required = chosen
    else:
        chosen, required = list(PROCEDURES), []
    data = read_dataset(args.dataset, limits=Limits.from_params(base))
    for entry, exp in data:
        missing = [c for c in COMPLETE if getattr(exp, c) is None]
        if missing:
            raise DatasetError(
                f"{data.root / entry.file}: no {' or '.join(missing)} column: identification "
                f"reads the position and both chamber pressures (Eq. 7's flow samples of the "
                f"locked tests, the valve sweep, the hysteresis, the friction by Newton's law; "
                f"one chamber alone charges only from its rest pressure up, and the flow map "
                f"below it would be extrapolated); with fewer sensors 'jetpipe diagnose' judges "
                f"the model on what there is (docs/real_logs.md)")
    signs = read_signs(data, base)
    said = [f"signs: {signs.words}"] if signs and (signs.changes or signs.against) else []
    if said:
        data = rewritten(data, signs.changes)
    ident = identify(data, base, chosen, required)
    ident.notes.extend(said)
    text = summary(ident)
    header = "".join(f"# {line}\n" for line in text.splitlines())
    fileio.write_files({out: header + ident.params.to_ros_yaml(), report: html_report(ident)})
    print(text)
    print(f"parameters -> {out}\nreport -> {report}")
    return 0


def read_signs(data, base):
    """Which way ``data``'s signals count, against the model ``base``
    (:func:`jetpipe_ros.diagnosis.signs.measure`); None for records too short to compare (the
    diagnosis' own minimum of training data), which the procedures then judge alone."""
    from jetpipe_ros.dataset import DatasetError
    from jetpipe_ros.diagnosis.data import prepare
    from jetpipe_ros.diagnosis.signs import measure

    try:
        prepared = prepare(data)
    except DatasetError:
        return None
    return measure(data, prepared, base)


def add_command(subparsers) -> None:
    """``jetpipe identify``: identify the model's parameters from a dataset."""
    cmd = subparsers.add_parser(
        "identify", help="identify model parameters from a dataset (the paper's procedures)",
        description="Run the paper's identification procedures (flow map, valve dynamics, "
                    "hysteresis, friction planes) on the experiments of a dataset that feed "
                    "them, write a parameter YAML the simulator loads and an HTML report.")
    cmd.add_argument("dataset", help="dataset directory (dataset.yaml + CSVs, docs/data.md)")
    cmd.add_argument("--out", required=True, help="parameter YAML to write (ROS params layout)")
    cmd.add_argument("--params", help="starting parameters (YAML); default: the nominal model")
    cmd.add_argument("--report", help="HTML report path; default: OUT with .report.html")
    cmd.add_argument("--procedures", help="comma-separated subset of flow_map (Eq. 8), "
                                          "flow_table (its correction table), valve, "
                                          "hysteresis, friction; each listed one must run "
                                          "(default: all that the data allow)")
    cmd.set_defaults(func=_run)
