"""``jetpipe identify DATASET_DIR --out params.yaml``: the paper's procedures on a dataset.

Before any procedure runs the records' conventions are read as the diagnosis reads them:

- the signs (:mod:`jetpipe_ros.diagnosis.signs`): a command, position or pressures counted the
  other way would otherwise be identified as logged (a command counted the other way as a
  mirrored flow map), parameters of no actuator of the data contract;
- the time base, by the controller's reaction alone
  (:func:`jetpipe_ros.diagnosis.alignment.controller_reaction`): a logger that writes each
  measurement a row early would otherwise take a row off the valve's delay (the default
  campaign logged so: 1.19 ms identified where the aligned record gives 2.19). The
  diagnosis' other evidence, the model's own delay, is not used: identification is what
  measures that delay. Without a closed-loop record nothing tells, and the summary says so.

What was read otherwise than logged, or could not be checked, is said in the summary (on the
console, in the parameter file's header and in the report), with what the reader did to the
records (units converted, stamps snapped to their grid, rows filled over gaps).

Both outputs (the parameter YAML and the HTML report) are checked before the work and written
together at the end: both or, on an error, neither.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the command's imports wait until it runs: the CLI starts fast
    from jetpipe_ros.dataset import Dataset
    from jetpipe_ros.model import ModelParams


def _run(args) -> int:
    from jetpipe_ros import fileio
    from jetpipe_ros.dataset import COMPLETE, DatasetError, grouped_notes, read_dataset
    from jetpipe_ros.identify.identify import PROCEDURES, identify
    from jetpipe_ros.identify.report import html_report, summary
    from jetpipe_ros.model import ModelParams, load_params
    from jetpipe_ros.model.limits import Limits
    from jetpipe_ros.progress import Progress

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
    progress = Progress(args.quiet)
    progress(f"reading {args.dataset}")
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
    progress("reading the records' signs and time base")
    data, said = read_conventions(data, base)
    ident = identify(data, base, chosen, required, progress)
    ident.notes.extend(grouped_notes(data.notes) + said)
    if any(not exp.measured.all() for _, exp in data):
        ident.notes.append("the procedures fit the measured rows only: not the rows filled over "
                           "a logger's gaps nor the derivatives whose window reaches them (the "
                           "valve's fit neither the 30 ms after a gap of two rows or more): "
                           "docs/identification.md")
    text = summary(ident)
    header = "".join(f"# {line}\n" for line in text.splitlines())
    fileio.write_files({out: header + ident.params.to_ros_yaml(), report: html_report(ident)})
    print(text)
    print(f"parameters -> {out}\nreport -> {report}")
    return 0


def read_conventions(data: Dataset, base: ModelParams) -> tuple[Dataset, list[str]]:
    """``data`` read as the data contract counts its signs and pairs its rows, and what was
    said of it: the signs against the model ``base``
    (:func:`jetpipe_ros.diagnosis.signs.measure`), the time base by
    the controller's reaction. Records too short for the diagnosis' comparison (its minimum of
    training data) are returned as logged, nothing said: the procedures judge them alone."""
    from jetpipe_ros.dataset import DatasetError
    from jetpipe_ros.diagnosis.alignment import controller_reaction
    from jetpipe_ros.diagnosis.data import prepare, shifted
    from jetpipe_ros.diagnosis.signs import read

    try:
        prepared = prepare(data)
    except DatasetError:
        return data, []
    signs, data, prepared = read(data, prepared, base)
    said = [f"signs: {signs.words}"] if signs.changes or signs.against else []
    rows, z = controller_reaction(prepared)
    ms = prepared.dt * 1e3
    if rows is None:
        said.append(f"time base: not checked: no closed-loop record whose controller reacts to "
                    f"the position's noise, which alone tells where a logger put the "
                    f"measurements without a model; a logger that wrote each measurement a row "
                    f"early (after the command beside it acted) would make the valve's delay "
                    f"{ms:.3g} ms shorter here: declare it in dataset.yaml (measured: "
                    f"after_command; docs/real_logs.md)")
    elif rows:
        data = shifted(data, rows)
        said.append(f"time base: the closed-loop records' controller reacts to the position "
                    f"{abs(rows)} row(s) {'after' if rows > 0 else 'before'} the row it is "
                    f"logged on ({z:.0f} standard errors): the logger wrote each measurement "
                    f"{abs(rows)} row(s) {'early' if rows > 0 else 'late'}; moved "
                    f"{abs(rows) * ms:.3g} ms {'later' if rows > 0 else 'earlier'} before "
                    f"identifying, as the diagnosis does")
    return data, said


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
    cmd.add_argument("--quiet", action="store_true", help="no progress lines (on stderr)")
    cmd.add_argument("--procedures", help="comma-separated subset of flow_map (Eq. 8), "
                                          "flow_table (its correction table), valve, "
                                          "hysteresis, friction; each listed one must run "
                                          "(default: all that the data allow)")
    cmd.set_defaults(func=_run)
