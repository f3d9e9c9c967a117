"""The ``jetpipe`` command line: offline tools that need no ROS.

Each sub-command lives with the tool it runs: a module listed in :data:`COMMANDS` defines
``add_command(subparsers)``, which adds its parser and sets ``func`` to a function taking the
parsed arguments and returning the exit status. Heavy imports belong inside that function.
Bad input and file-system errors (a path that cannot be read or written) end the command with
one line naming the file and the reason, and exit status 2; commands check their output paths
before the work and write atomically (:mod:`jetpipe_ros.fileio`), so nothing is half-written.

Every command runs with one BLAS thread (:func:`threadpoolctl.threadpool_limits`): the tools'
linear algebra is on small matrices (a filter's discretisation, a few knobs' least squares),
where a pool of threads only spins and takes the cores the numba kernels and worker processes
need. Measured on a 2-core machine with another job running: the placement of an unlisted
cause (:mod:`jetpipe_ros.diagnosis.placement`) 76-78 s with the default pool, 15-17 s with one
thread (profiled, scipy's matrix exponential alone took 32 s of 84).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from threadpoolctl import threadpool_limits

from jetpipe_ros import __version__
from jetpipe_ros.dataset import DatasetError
from jetpipe_ros.fileio import FileError
from jetpipe_ros.model import ParameterError

#: Modules that contribute a sub-command, in the order ``jetpipe --help`` lists them.
COMMANDS = (
    "jetpipe_ros.replay",
    "jetpipe_ros.bag.export",
    "jetpipe_ros.workflows.cli",
    "jetpipe_ros.workflows.identify_command",
    "jetpipe_ros.twin.cli",
    "jetpipe_ros.identify.seal_cli",
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one sub-command per tool."""
    parser = argparse.ArgumentParser(
        prog="jetpipe", description="Jet-pipe servo actuator: simulation and sim-to-real tools.")
    parser.add_argument("--version", action="version", version=f"jetpipe {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for module in COMMANDS:
        importlib.import_module(module).add_command(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``jetpipe``; returns the process exit status (2 for bad input)."""
    args = build_parser().parse_args(argv)
    try:
        with threadpool_limits(1):
            return args.func(args)
    except (ParameterError, DatasetError, FileError) as exc:
        print(f"jetpipe {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # any other file-system error: the path and the reason
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"jetpipe {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"jetpipe {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
