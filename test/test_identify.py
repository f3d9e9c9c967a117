"""jetpipe identify: each procedure recovers the pinned model (DESIGN.md s.2, the paper's
coefficients) from simulated noisy recordings; the identified YAML reproduces a held-out run;
bad or insufficient data is named."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize

from jetpipe_ros.cli import main
from jetpipe_ros.dataset import DatasetError, Entry, Experiment, read_dataset, write_dataset
from jetpipe_ros.identify import identify
from jetpipe_ros.identify import synthetic as syn
from jetpipe_ros.identify.experiments import Recording
from jetpipe_ros.identify.friction import paper_planes
from jetpipe_ros.identify.hysteresis import identify_hysteresis
from jetpipe_ros.identify.valve import peak, response
from jetpipe_ros.model import ModelParams, load_params
from jetpipe_ros.model.flow import mass_flow
from jetpipe_ros.model.params import FLOW_COEFFICIENTS
from jetpipe_ros.replay import replay

NOISY = ModelParams().with_values({"sensors.noise": True, "sensors.seed": 11})
ENTRY = ((1, 9.92), (4.15, 9.92), (7.18, 9.9), (1, 6.93), (1, 3.96), (4.23, 8.89),
         (3.02, 5.89), (2.99, 4.2))
EXIT = ((4.015, 1), (6.89, 1), (8.98, 1), (10.115, 8.89), (10.205, 4.195))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("id") / "paper"
    syn.paper_dataset(root, NOISY, entry=ENTRY, exit_=EXIT, charge=1.5, discharge=1.0)
    return read_dataset(root)


@pytest.fixture(scope="module")
def result(dataset):
    return identify(dataset)


def test_every_procedure_ran_on_its_experiments(result):
    assert result.skipped == {}
    kinds = {r.name: r.kind for r in result.recordings}
    assert kinds["charge_3p4V"] == "charge" and kinds["valve_sweep"] == "sweep"
    assert kinds["slow_ramps"] == "ramp" and kinds["square_0p6V"] == "validation"
    assert kinds["friction_1_6p93bar"] == "friction"


def test_flow_map_recovers_eq8_on_the_identified_range(result):
    """Within the paper's own fit error (max 0.0005 kg/s) of Eq. 8 wherever data was taken."""
    s = result.flow.samples
    err = mass_flow(result.flow.coefficients, s.u, s.p_bar) - mass_flow(FLOW_COEFFICIENTS, s.u,
                                                                        s.p_bar)
    assert np.max(np.abs(err)) < 5e-4
    assert np.sqrt(np.mean(err ** 2)) < 5e-5
    assert result.flow.max_error < 1e-3
    null = optimize.brentq(lambda p: mass_flow(result.flow.coefficients, 0.0, p)[0], 2.0, 8.0)
    assert null == pytest.approx(4.165, abs=0.05)


def test_valve_recovers_resonance_delay_and_lead_lag(result):
    ident = result.params
    f_r, gain = peak(ident)
    assert f_r == pytest.approx(49.7, abs=0.5)  # DESIGN.md s.2: gain peak at 49.7 Hz
    assert gain == pytest.approx(peak(ModelParams())[1], rel=0.03)
    assert ident["valve.delay"] == pytest.approx(0.002, abs=3e-4)
    assert ident["valve.back_emf_constant"] == pytest.approx(0.1, rel=0.15)
    # The whole chain (Eq. 4, 9, 10) up to 60 Hz: the lead-lag's zero and pole trade off
    # against each other and K_b, so the response is what is pinned (gain 6 %, phase 8 deg;
    # the kernel's explicit pressure step adds ~0.1 ms of apparent delay).
    f = np.linspace(1.0, 60.0, 300)
    ratio = response(ident, f) / response(ModelParams(), f)
    assert np.max(np.abs(np.abs(ratio) - 1.0)) < 0.06
    assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 8.0
    assert result.valve.rms_error < 1.2 * 500.0  # residual at the pressure sensor noise


def _ramp(params):
    cols = syn.slow_ramps(params)
    exp = Experiment(**{k: cols[k] for k in ("t", "u", "y", "p1", "p2")})
    return [Recording(Entry("ramp.csv", piston="locked"), exp, "ramp")]


@pytest.mark.parametrize(("half_width", "elements"), [(0.0, 1), (0.25, 1), (0.15, 4)])
def test_hysteresis_half_width(half_width, elements):
    truth = NOISY if half_width == 0.0 else NOISY.with_effect(
        "valve_hysteresis", half_width=half_width, elements=elements)
    h = identify_hysteresis(_ramp(truth), NOISY, FLOW_COEFFICIENTS)
    assert h.half_width == pytest.approx(half_width, abs=0.02)
    assert h.significant == (half_width > 0.0)
    assert h.midline_slope == pytest.approx(1.0, abs=0.02)  # midpoint lines: u = u_eq


@pytest.mark.parametrize("phase", ["entry", "exit"])
def test_friction_planes_match_the_papers(result, phase):
    """Identified planes against Eq. 20-27 at the test pressures: forces within 5 % or 3 N,
    viscosity within 2 %, the Stribeck velocity (least visible at 1 kHz) within 15 % or
    1.5 mm/s."""
    planes, paper = result.params, paper_planes(phase)
    tol = {"breakaway": (0.05, 3.0), "stribeck_velocity": (0.15, 1.5e-3),
           "viscous": (0.02, 0.0), "coulomb": (0.05, 3.0)}
    for t in (t for t in result.friction.tests if t.phase == phase):
        for q, (rel, absolute) in tol.items():
            c, c0 = planes[f"friction.{phase}.{q}"], paper[q]
            got = c[0] + c[1] * t.p1_bar + c[2] * t.p2_bar
            want = c0[0] + c0[1] * t.p1_bar + c0[2] * t.p2_bar
            assert got == pytest.approx(want, rel=rel, abs=absolute), (q, t.name)
    assert max(result.friction.max_relative_error[phase].values()) < 0.2


def test_friction_worked_example(result):
    """Sec. 4.2.3 at (1, 6.93) bar: F_S -95 N, v_s -0.015 m/s, F_v 3440 N s/m, F_C -56 N."""
    test = next(t for t in result.friction.tests if t.name == "friction_1_6p93bar")
    assert test.values["breakaway"] == pytest.approx(-95.0, rel=0.05)
    assert test.values["stribeck_velocity"] == pytest.approx(-0.015, rel=0.15)
    assert test.values["viscous"] == pytest.approx(3440.0, rel=0.02)
    assert test.values["coulomb"] == pytest.approx(-56.0, rel=0.06)


def test_round_trip_through_the_cli(dataset, tmp_path, capsys):
    """identify -> YAML -> simulate the held-out square wave: within 0.5 mm and 0.03 bar RMS
    of the recording (sensor noise alone: 0.015 mm, 0.005 bar)."""
    out = tmp_path / "params.yaml"
    assert main(["identify", str(dataset.root), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "paper: max about 0.0005 kg/s" in printed and "(paper: < 5 %)" in printed
    assert (tmp_path / "params.report.html").read_text().count("<img") >= 5
    params = load_params(out)
    exp = next(x for e, x in dataset if e.role == "holdout")
    trace = replay(params, exp)
    assert np.sqrt(np.mean((trace.y - exp.y) ** 2)) < 5e-4
    assert np.sqrt(np.mean((trace.p1 - exp.p1) ** 2)) < 3e3
    assert np.ptp(trace.y) > 0.04  # the square wave moves the piston stop to stop


def _write(tmp_path, runs):
    return read_dataset(write_dataset(tmp_path / "ds", runs))


def test_no_usable_experiment_names_every_procedure(tmp_path, capsys):
    u = np.zeros(500)
    cols = syn._columns(NOISY, u)
    root = write_dataset(tmp_path / "ds", [(Entry("idle.csv", piston="free"), cols)])
    out = tmp_path / "p.yaml"
    assert main(["identify", str(root), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    for what in ("flow map: no constant-volume charge/discharge test", "valve dynamics: no",
                 "hysteresis: no slow ramp", "friction: no friction test"):
        assert what in err
    assert not out.exists() and not (tmp_path / "p.report.html").exists()


def test_too_few_voltages_and_a_short_sweep_are_named(tmp_path):
    ds = _write(tmp_path, [
        (Entry("c1.csv", piston="locked"), syn.charge_discharge(NOISY, 1.0, 1.0, 1.0)),
        (Entry("c2.csv", piston="locked"), syn.charge_discharge(NOISY, 2.0, 1.0, 1.0)),
        (Entry("sw.csv", piston="locked"), syn.valve_sweep(NOISY, f1=20.0, duration=3.0))])
    with pytest.raises(DatasetError, match=r"flow map: .* 4 distinct voltage\(s\)"):
        identify(ds, procedures=["flow_map"], required=["flow_map"])
    with pytest.raises(DatasetError, match=r"valve dynamics: the sweep\(s\) sw reach 2\d Hz"):
        identify(ds, procedures=["valve"], required=["valve"])
    with pytest.raises(DatasetError, match="nothing identified: flow_map: .* valve: .* "
                                           "hysteresis: .* friction: "):
        identify(ds)


def test_friction_test_released_at_once_is_skipped_with_the_reason(tmp_path):
    held = syn.friction_test(NOISY, 1.0, 6.93, ramp_rate=1e7)  # load gone in one sample
    ramped = [syn.friction_test(NOISY, p1, p2) for p1, p2 in ENTRY[3:6]]
    ds = _write(tmp_path, [(Entry("jump.csv", extra={"regulated": True}), held)]
                + [(Entry(f"r{i}.csv", extra={"regulated": True}), c)
                   for i, c in enumerate(ramped)])
    res = identify(ds, procedures=["friction"])
    notes = " ".join(res.friction.skipped)
    assert "test jump" in notes and "release the piston progressively" in notes
    assert "exit phase planes not identified" in notes
    assert "friction.entry.viscous" in res.changes()
