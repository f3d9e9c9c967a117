"""``jetpipe selfcheck``: the diagnosis judged on data whose effect is withheld.

Each case switches on one effect (or two, or none) at a random realistic size, sometimes in a
form the diagnosis has no candidate for (a multi-element hysteresis, an orifice leak, a
heat-transfer thermal model), simulates a dataset with sensor noise, and runs the diagnosis on
the dataset directory alone. The truth stays here: the diagnosis reads only what a user would
give it. Then the verdicts are scored: top-1 accuracy (an effect too small to show in the
experiments counts as correctly answered by ``none``), a confusion matrix, the recovery of the
fitted parameters, and the held-out shrinkage.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.diagnosis.diagnose import diagnose
from jetpipe_ros.model import EFFECTS, ModelParams, simulate

#: Realistic sizes (DESIGN.md s.3): name -> sampler of the effect's parameters.
SIZES: dict[str, Callable[[np.random.Generator], dict]] = {
    "valve_delay": lambda r: {"delay": r.uniform(1e-3, 5e-3)},
    "valve_lag": lambda r: {"corner_frequency": math.exp(r.uniform(math.log(10), math.log(60)))},
    "valve_hysteresis": lambda r: {"half_width": r.uniform(0.1, 0.4)},
    "supply_pressure": lambda r: {"pressure": r.uniform(6e5, 9e5)},
    "thermal": lambda r: {"polytropic_index": r.uniform(1.1, 1.4)},
    "leakage": lambda r: {"cross_coefficient": r.uniform(2e-10, 8e-10)},
    "friction_dynamics": lambda r: {"bristle_stiffness": math.exp(r.uniform(math.log(1e4),
                                                                            math.log(1e6)))},
    "moving_mass": lambda r: {"mass": r.choice([r.uniform(0.5, 0.7), r.uniform(2.0, 5.0)])},
    "sensor_dynamics": lambda r: {"time_constant": r.uniform(1e-3, 1e-2),
                                  "bias": r.choice([-1.0, 1.0]) * r.uniform(1e3, 1e4)},
}
#: Effects in a form no candidate has: (effect, sampler) by variant name.
VARIANTS: dict[str, tuple[str, Callable[[np.random.Generator], dict]]] = {
    "hysteresis_multi_element": ("valve_hysteresis", lambda r: {
        "half_width": r.uniform(0.15, 0.4), "elements": 4}),
    "orifice_leak": ("leakage", lambda r: {"form": "orifice",
                                           "cross_area": r.uniform(0.6e-7, 1.5e-7)}),
    "heat_transfer_thermal": ("thermal", lambda r: {
        "form": "heat_transfer", "heat_transfer": math.exp(r.uniform(math.log(0.2),
                                                                     math.log(2.0)))}),
}
PAIRS = (("valve_lag", "leakage"), ("valve_hysteresis", "thermal"))
#: The cycle of case kinds: none, every effect, every variant, the pairs.
KINDS = ("none", *EFFECTS, *VARIANTS, *("+".join(p) for p in PAIRS))
#: A truth whose noise-free signature is below this fraction of the noise variance cannot be
#: seen in the experiments; ``none`` is then a correct answer.
VISIBLE = 0.02


@dataclass
class Case:
    """One withheld truth and what the diagnosis said about it."""

    index: int
    kind: str
    effects: dict[str, dict]  #: effect -> parameters switched on
    seed: int
    visible: bool = True
    verdict: str = ""
    verdict_params: dict = field(default_factory=dict)
    confidence: float = 0.0
    shrinkage: float = 0.0
    gap_nominal: float = 0.0
    gap_augmented: float = 0.0
    seconds: float = 0.0

    @property
    def truth(self) -> str:
        """The expected answer: the effect family names joined by '+', or none."""
        return "+".join(sorted(self.effects)) or "none"

    @property
    def correct(self) -> bool:
        """The verdict names the truth (or says none for an invisible truth)."""
        got = "+".join(sorted(self.verdict.split("+"))) if self.verdict != "none" else "none"
        return got == self.truth or (not self.visible and got == "none")

    def truth_params(self) -> ModelParams:
        """The model the data were simulated with."""
        p = ModelParams()
        for effect, kw in self.effects.items():
            p = p.with_effect(effect, **kw)
        return p


def make_cases(n: int, seed: int) -> list[Case]:
    """``n`` cases cycling through :data:`KINDS`, sizes drawn with ``seed``."""
    rng = np.random.default_rng(seed)
    cases = []
    for i in range(n):
        kind = KINDS[i % len(KINDS)]
        if kind == "none":
            effects: dict[str, dict] = {}
        elif kind in VARIANTS:
            effect, sampler = VARIANTS[kind]
            effects = {effect: sampler(rng)}
        else:
            effects = {e: SIZES[e](rng) for e in kind.split("+")}
        cases.append(Case(i, kind, effects, int(rng.integers(1, 2**31 - 1))))
    return cases


def signature(truth: ModelParams, dataset_dir: Path) -> float:
    """Noise-free difference between the truth and the nominal model on the dataset's
    commands, as a fraction of the sensor noise variance (signals averaged)."""
    ds = read_dataset(dataset_dir)
    nominal = ModelParams()
    sigma = {"y": nominal["sensors.position_sigma"], "p1": nominal["sensors.pressure_sigma"],
             "p2": nominal["sensors.pressure_sigma"]}
    ratios = []
    for entry, exp in ds:
        changes = {"mechanics.locked": entry.locked, "sensors.noise": False}
        a = simulate(truth.with_values(changes), exp.u)
        b = simulate(nominal.with_values(changes), exp.u)
        for s in (("p1", "p2") if entry.locked else ("y", "p1", "p2")):
            d = getattr(a, f"{s}_meas") - getattr(b, f"{s}_meas")  # as the sensors read them
            ratios.append(float(np.mean(d ** 2)) / sigma[s] ** 2)
    return float(np.mean(ratios))


def run_selfcheck(n: int, seed: int, make_dataset: Callable[[ModelParams, Path, int], None],
                  out_dir: Path | None = None, workers: int = 2,
                  progress: Callable[[str], None] = print) -> dict:
    """Run ``n`` cases; ``make_dataset(params, root, seed)`` writes a noisy dataset to root."""
    cases = make_cases(n, seed)
    work = Path(tempfile.mkdtemp(prefix="jetpipe-selfcheck-"))
    began = time.perf_counter()
    try:
        for case in cases:
            t0 = time.perf_counter()
            data = work / f"case{case.index:02d}"
            truth = case.truth_params()
            make_dataset(truth.with_values({"sensors.noise": True,
                                            "sensors.seed": case.seed % 100000}), data,
                         case.seed)
            case.visible = not case.effects or signature(truth, data) >= VISIBLE
            result = diagnose(data, work / f"out{case.index:02d}", workers=workers, quiet=True)
            v = result["verdict"]
            case.verdict, case.verdict_params = v["effect"], v["params"]
            case.confidence = v["confidence"]
            case.gap_nominal, case.gap_augmented = (result["gap"]["nominal"],
                                                    result["gap"]["augmented"])
            case.shrinkage = result["gap"]["shrinkage"]
            case.seconds = time.perf_counter() - t0
            progress(f"[{case.index + 1}/{n}] {case.kind:26s} truth {case.truth:28s} -> "
                     f"{case.verdict:28s} {'ok ' if case.correct else 'MISS'} "
                     f"shrinkage {100 * case.shrinkage:4.0f} %  ({case.seconds:.0f} s)")
            shutil.rmtree(data, ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    summary = summarise(cases, time.perf_counter() - began)
    if out_dir is not None:
        from jetpipe_ros import fileio

        fileio.write_files({out_dir / "selfcheck.json": fileio.to_json(summary) + "\n",
                            out_dir / "selfcheck.md": render(summary)})
    return summary


def summarise(cases: list[Case], seconds: float) -> dict:
    """Accuracy, confusion matrix, parameter recovery and shrinkage of a set of cases."""
    labels = sorted({c.truth for c in cases} | {c.verdict for c in cases})
    confusion = {t: {v: sum(1 for c in cases if c.truth == t and c.verdict == v)
                     for v in labels} for t in sorted({c.truth for c in cases})}
    recovery = []
    for c in cases:
        if c.correct and len(c.effects) == 1 and c.kind in EFFECTS:
            (effect, truth), = c.effects.items()
            for k, x in truth.items():
                got = c.verdict_params.get(k)
                if isinstance(x, float) and got is not None:
                    recovery.append({"case": c.index, "effect": effect, "param": k,
                                     "truth": x, "fitted": got,
                                     "rel_error": abs(got - x) / abs(x)})
    with_effect = [c for c in cases if c.effects and c.visible]
    return {
        "cases": len(cases), "seconds": seconds,
        "top1_accuracy": float(np.mean([c.correct for c in cases])),
        "none_correct": all(c.correct for c in cases if not c.effects),
        "variant_accuracy": float(np.mean([c.correct for c in cases if c.kind in VARIANTS]))
        if any(c.kind in VARIANTS for c in cases) else None,
        "median_shrinkage": float(np.median([c.shrinkage for c in with_effect]))
        if with_effect else None,
        "median_param_rel_error": float(np.median([r["rel_error"] for r in recovery]))
        if recovery else None,
        "confusion": confusion, "recovery": recovery,
        "results": [{"case": c.index, "kind": c.kind, "truth": c.truth, "effects": c.effects,
                     "visible": c.visible, "verdict": c.verdict, "params": c.verdict_params,
                     "confidence": c.confidence, "correct": c.correct,
                     "gap_nominal": c.gap_nominal, "gap_augmented": c.gap_augmented,
                     "shrinkage": c.shrinkage, "seconds": c.seconds} for c in cases],
    }


def render(summary: dict) -> str:
    """The self-check as Markdown: headline figures, confusion matrix, parameter recovery."""
    lines = [f"# jetpipe selfcheck: {summary['cases']} cases in {summary['seconds']:.0f} s", "",
             f"- top-1 accuracy: {100 * summary['top1_accuracy']:.0f} %",
             f"- `none` answered correctly on every effect-free case: "
             f"{'yes' if summary['none_correct'] else 'no'}"]
    if summary["variant_accuracy"] is not None:
        lines.append(f"- accuracy on effects in a form no candidate has: "
                     f"{100 * summary['variant_accuracy']:.0f} %")
    if summary["median_shrinkage"] is not None:
        lines.append(f"- median held-out shrinkage (visible effects): "
                     f"{100 * summary['median_shrinkage']:.0f} %")
    if summary["median_param_rel_error"] is not None:
        lines.append(f"- median relative error of recovered parameters: "
                     f"{100 * summary['median_param_rel_error']:.1f} %")
    conf = summary["confusion"]
    cols = sorted({v for row in conf.values() for v, n in row.items() if n})
    lines += ["", "## Confusion matrix (rows: truth, columns: verdict)", "",
              "| truth | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for t, row in conf.items():
        lines.append(f"| {t} | " + " | ".join(str(row.get(c, 0) or "") for c in cols) + " |")
    lines += ["", "## Cases", "", "| # | kind | truth | verdict | ok | shrinkage | confidence |",
              "|---|---|---|---|---|---|---|"]
    for r in summary["results"]:
        ok = "yes" if r["correct"] else "**no**"
        vis = "" if r["visible"] else " (too small to see)"
        lines.append(f"| {r['case']} | {r['kind']}{vis} | {r['truth']} | {r['verdict']} | {ok} "
                     f"| {100 * r['shrinkage']:.0f} % | {r['confidence']:.2f} |")
    if summary["recovery"]:
        lines += ["", "## Parameter recovery", "", "| effect | parameter | truth | fitted | "
                  "error |", "|---|---|---|---|---|"]
        for r in summary["recovery"]:
            lines.append(f"| {r['effect']} | {r['param']} | {r['truth']:.4g} | "
                         f"{r['fitted']:.4g} | {100 * r['rel_error']:.1f} % |")
    return "\n".join(lines) + "\n"
