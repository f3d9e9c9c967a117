"""Draw docs/friction_loops.png and docs/friction_drift.png, docs/friction.md's pictures: the
shipped friction-rig records (test/data/friction-seals) fitted as `jetpipe friction` fits them;
NAPN at 3 bar measured against the static and the selected form, and each record's sliding
level per pass over time. About ten seconds:

    .venv/bin/python docs/figures/make_friction.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from jetpipe_ros.dataset import read_records  # noqa: E402
from jetpipe_ros.identify.drift import level_drift  # noqa: E402
from jetpipe_ros.identify.seal import identify_seal, prepare  # noqa: E402
from jetpipe_ros.identify.seal_report import drift_figure, loop_figure  # noqa: E402

HERE = Path(__file__).resolve().parent
DOCS = HERE.parent
RECORDS = DOCS.parent / "test" / "data" / "friction-seals"


def main() -> None:
    preps = [prepare(r) for r in read_records(RECORDS)]
    napn = [p for p in preps if p.record.name == "NAPN_3bar"]
    result = identify_seal("NAPN", napn)
    loop_figure(result, napn).savefig(DOCS / "friction_loops.png", dpi=80)
    drifts = {p.record.name: level_drift(p) for p in preps}
    drift_figure(preps, drifts).savefig(DOCS / "friction_drift.png", dpi=80)
    print(f"wrote {DOCS / 'friction_loops.png'} and {DOCS / 'friction_drift.png'}")


if __name__ == "__main__":
    main()
