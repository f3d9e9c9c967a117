"""Identification speed: wall time of each procedure of ``jetpipe identify`` on the paper's
full campaign simulated with noise (7 charge/discharge tests of 6.2 s, a 6 s sweep, 12.5 s of
ramps, 26 + 11 friction tests). Prints a markdown table; compare rows, not machines. Measured
(2 cores, shared): friction 0.38 s with Newton's law alone, 23 s with the output-error fit that
replays each test (identify() 13.6 -> 34.8 s).
Usage: .venv/bin/python bench/bench_identify.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.identify.experiments import of_kind, recordings
from jetpipe_ros.identify.flow_map import identify_flow_map
from jetpipe_ros.identify.friction import identify_friction
from jetpipe_ros.identify.hysteresis import identify_hysteresis
from jetpipe_ros.identify.identify import identify
from jetpipe_ros.identify.synthetic import paper_dataset
from jetpipe_ros.identify.valve import identify_valve
from jetpipe_ros.model import ModelParams


def _timed(fn):  # type: ignore[no-untyped-def]
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def main() -> None:
    params = ModelParams().with_values({"sensors.noise": True, "sensors.seed": 1})
    with tempfile.TemporaryDirectory() as tmp:
        root, t_gen = _timed(lambda: paper_dataset(Path(tmp) / "paper", params))
        ds, t_read = _timed(lambda: read_dataset(root))
        recs = recordings(ds)
        identify(ds)  # warm-up: numba and scipy imports
        flow, t_flow = _timed(lambda: identify_flow_map(of_kind(recs, "charge"), params))
        _, t_valve = _timed(lambda: identify_valve(of_kind(recs, "sweep"), params,
                                                   flow.coefficients))
        _, t_hyst = _timed(lambda: identify_hysteresis(of_kind(recs, "ramp"), params,
                                                       flow.coefficients))
        _, t_fric = _timed(lambda: identify_friction(of_kind(recs, "friction"), params))
        _, t_all = _timed(lambda: identify(ds))
    rows = [("simulate the campaign (synthetic.paper_dataset)", t_gen),
            ("read the dataset", t_read), ("flow map", t_flow), ("valve dynamics", t_valve),
            ("hysteresis", t_hyst), ("friction (37 tests, each replayed from 10 starts)", t_fric),
            ("identify() total, with replays", t_all)]
    print("| step | wall [s] |\n|---|---|")
    for label, seconds in rows:
        print(f"| {label} | {seconds:.2f} |")


if __name__ == "__main__":
    main()
