"""Draw docs/figures/tour.png, the README's picture: a recording of an actuator with a 20 Hz
valve lag (the offline campaign on the model, sensor noise on) against the nominal model and the
model `jetpipe diagnose` augmented, on a held-out sine sweep. About a minute:

    .venv/bin/python docs/figures/make_tour.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from jetpipe_ros.campaign import default_campaign, run_campaign_offline  # noqa: E402
from jetpipe_ros.dataset import read_dataset  # noqa: E402
from jetpipe_ros.workflows import diagnose  # noqa: E402
from jetpipe_ros.model import ModelParams, load_params, simulate  # noqa: E402

HERE = Path(__file__).resolve().parent
SHOWN = "sweep_0p8V"
WINDOW = (3.0, 3.6)  # s of the sweep shown (about 20-30 Hz)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        truth = ModelParams().with_effect("valve_lag", corner_frequency=20.0).with_values(
            {"sensors.noise": True})
        data = run_campaign_offline(truth, default_campaign(), Path(tmp) / "data", seed=3)
        result = diagnose(data, Path(tmp) / "diag", workers=1, quiet=True)
        augmented = load_params(Path(tmp) / "diag" / "augmented.yaml")
        entry, exp = next((e, x) for e, x in read_dataset(data) if e.name == SHOWN)
    start = {"mechanics.initial_position": float(exp.y[0]),
             "chamber.initial_pressure_1": float(exp.p1[0]),
             "chamber.initial_pressure_2": float(exp.p2[0])}
    nominal = simulate(ModelParams().with_values(start), exp.u)
    fitted = simulate(augmented.with_values(start), exp.u)
    keep = (exp.t >= WINDOW[0]) & (exp.t <= WINDOW[1])
    v, g = result["verdict"], result["gap"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 4.2), sharex=True,
                                      constrained_layout=True)
    top.plot(exp.t[keep], exp.y[keep] * 1e3, color="0.2", lw=1.0, label="recorded")
    top.plot(exp.t[keep], nominal.y[keep] * 1e3, lw=1.0, label="nominal model")
    found = ", ".join(f"{k} {x:.3g}" for k, x in v["params"].items())
    print(f"verdict {v['effect']} ({v.get('candidate')}): {found}")
    top.plot(exp.t[keep], fitted.y[keep] * 1e3, lw=1.0, ls="--",
             label=f"augmented model ({v['effect']}, found by jetpipe diagnose)")
    top.set_ylabel("position y [mm]")
    top.legend(loc="upper right", fontsize=7, framealpha=0.9)
    top.set_title(f"{SHOWN} ({entry.role}): held-out gap {g['nominal']:.1f} % (nominal) -> "
                  f"{g['augmented']:.2f} % (augmented)", fontsize=9)
    bottom.plot(exp.t[keep], exp.p1[keep] / 1e5, color="0.2", lw=1.0)
    bottom.plot(exp.t[keep], nominal.p1[keep] / 1e5, lw=1.0)
    bottom.plot(exp.t[keep], fitted.p1[keep] / 1e5, lw=1.0, ls="--")
    bottom.set_ylabel("p1 [bar]")
    bottom.set_xlabel("t [s]")
    fig.savefig(HERE / "tour.png", dpi=80)


if __name__ == "__main__":
    main()
