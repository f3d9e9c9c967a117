"""``jetpipe identify DATASET_DIR --out params.yaml``: the paper's procedures on a dataset."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file renamed into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _run(args) -> int:
    from jetpipe_ros.dataset import DatasetError, read_dataset
    from jetpipe_ros.identify.identify import PROCEDURES, identify
    from jetpipe_ros.identify.report import html_report, summary
    from jetpipe_ros.model import ModelParams, load_params

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
    ident = identify(read_dataset(args.dataset), base, chosen, required)
    out = Path(args.out)
    report = Path(args.report) if args.report else out.with_suffix(".report.html")
    text = summary(ident)
    header = "".join(f"# {line}\n" for line in text.splitlines())
    page = html_report(ident)
    write_atomically(out, header + ident.params.to_ros_yaml())
    write_atomically(report, page)
    print(text)
    print(f"parameters -> {out}\nreport -> {report}")
    return 0


def add_command(subparsers) -> None:
    """``jetpipe identify``: identify the model's parameters from a dataset."""
    cmd = subparsers.add_parser(
        "identify", help="identify model parameters from a dataset (the paper's procedures)",
        description="Run the paper's identification procedures (flow map, valve dynamics, "
                    "hysteresis, friction planes) on the experiments of a dataset that feed "
                    "them, write a parameter YAML the simulator loads and an HTML report.")
    cmd.add_argument("dataset", help="dataset directory (dataset.yaml + CSVs, DESIGN.md s.5)")
    cmd.add_argument("--out", required=True, help="parameter YAML to write (ROS params layout)")
    cmd.add_argument("--params", help="starting parameters (YAML); default: the nominal model")
    cmd.add_argument("--report", help="HTML report path; default: OUT with .report.html")
    cmd.add_argument("--procedures", help="comma-separated subset of flow_map, valve, "
                                          "hysteresis, friction; each listed one must run "
                                          "(default: all that the data allow)")
    cmd.set_defaults(func=_run)
