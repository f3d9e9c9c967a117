"""Progress lines of long commands: on stderr, each with the time since the command started, so
a person watching (or a log file) sees the work move; stdout keeps the results."""

from __future__ import annotations

import sys
import time


class Progress:
    """Progress lines on stderr with elapsed time [s]; nothing when ``quiet``."""

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.start = time.perf_counter()

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{time.perf_counter() - self.start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)
