"""Where a gap starts (jetpipe_ros.diagnosis.placement): causes on no list, recorded on the plant
(written apart from the model), placed in their subsystem by experiments on the records."""

from pathlib import Path

import pytest

from jetpipe_ros.campaign import default_campaign, run_campaign_offline
from jetpipe_ros.dataset import read_dataset
from jetpipe_ros.diagnosis import residuals
from jetpipe_ros.diagnosis.data import Prepared, prepare
from jetpipe_ros.diagnosis.noise_floor import calibrate, twin
from jetpipe_ros.diagnosis.placement import PLACES, by_candidates, place
from jetpipe_ros.model import ModelParams
from jetpipe_ros.plant import Plant, PlantSpec
from jetpipe_ros.plant.logger import log

#: A short campaign with locked, open-loop and closed-loop experiments, three held out.
EXPERIMENTS = ("charge_2p86V", "valve_sweep_1V", "sweep_1p5V", "prbs_multilevel", "stick_slip",
               "square_3V_0p97Hz", "sweep_0p8V", "stick_slip_holdout")


def recorded(root: Path, effect: str, logger: str | None = None, **values: float) -> Prepared:
    """The short campaign recorded with sensor noise on the nominal plant with one real
    ``effect`` (rewritten by ``logger``, :data:`jetpipe_ros.plant.logger.LOGGERS`), prepared
    with its noise floor against the nominal model."""
    spec = PlantSpec().with_values({"sensors.noise": True}).with_effect(effect, **values)
    run_campaign_offline(spec.params, default_campaign().select(EXPERIMENTS), root, seed=3,
                         actuator=lambda p: Plant(spec.with_params(p)))
    if logger:
        log(logger, root, 4)
    prepared = prepare(read_dataset(root))
    prepared.floor, prepared.floor_windows = calibrate(prepared, ModelParams())
    return prepared


def placed(root: Path, effect: str, **values: float) -> dict:
    """:func:`recorded`, placed against the nominal model."""
    return place(recorded(root, effect, **values), ModelParams())


def experiment(found: dict, signal: str) -> dict:
    return next(e for e in found["experiments"] if e["signal"] == signal)


def test_a_lagging_position_sensor_is_placed_in_the_sensors(tmp_path):
    """A position transducer filtering through two 2 ms stages (4 ms of lag; a force
    proportional to the acceleration to the force balance): the position sensor's lag alone
    removes the gap, fitted at 4 ms, gain 1; the command's offset does not."""
    found = placed(tmp_path, "position_filter", time_constant=2e-3)
    assert found["subsystem"] == "sensors"
    y = experiment(found, "y")
    assert y["time_constant_s"] == pytest.approx(4e-3, abs=1e-3)
    assert y["gain"] == pytest.approx(1.0, abs=0.01) and y["removed"] > 0.8
    assert experiment(found, "u")["removed"] < PLACES


def test_a_valve_null_offset_is_placed_in_the_valve(tmp_path):
    """A jet pipe whose null is 0.06 V off: the command's offset alone removes the gap, fitted
    at 0.06 V within 5 mV; no one sensor's lag, gain and offset does."""
    found = placed(tmp_path, "null_offset", offset=0.06)
    assert found["subsystem"] == "valve"
    u = experiment(found, "u")
    assert u["null_offset_v"] == pytest.approx(0.06, abs=5e-3) and u["removed"] > 0.8
    assert max(experiment(found, s)["removed"] for s in ("y", "p1", "p2")) < PLACES


def test_a_force_that_depends_on_position_is_placed_in_the_mechanics(tmp_path):
    """A 10 kN/m load spring: no one signal explains it; the valve and chambers fed the
    measured motion miss by little, the piston driven by the measured pressures by far more."""
    prepared = recorded(tmp_path, "load_spring", stiffness=1e4)
    found = place(prepared, ModelParams())
    assert found["subsystem"] == "mechanics"
    assert max(e["removed"] for e in found["experiments"]) < PLACES
    replays = found["replays"]
    assert replays["mechanics"]["gap"] > 5 * replays["valve_and_chambers"]["gap"]
    # Its shape, in the force balance's error: a force proportional to the position, at the
    # spring's stiffness within 10 % (the term's coefficient is the error per metre: -k, the
    # model lacking the spring's pull back), not the end stops' cushioning.
    shape, _ = residuals.locate(prepared, twin(prepared, ModelParams()), ModelParams(),
                                ModelParams()["mechanics.stroke"])
    top = shape["missing"]["terms"][0]
    assert shape["missing"]["equation"] == "force balance" and top["term"] == "spring"
    assert top["coefficient"] == pytest.approx(-1e4, rel=0.1)  # -1.035e4 found


def test_with_the_position_alone_the_candidates_place_it(tmp_path):
    """The load spring with the position alone: neither subsystem replays apart (the chambers
    have no pressure to be compared with, the piston none to be driven by), and no one signal
    explains it, so the candidates that explain part of the gap place it, the largest share
    first, and say so. With no candidate explaining any of it, nothing places it: said, not
    guessed (the chamber was the answer by default before)."""
    prepared = recorded(tmp_path, "load_spring", "position_only", stiffness=1e4)
    leads = [("valve_lag:first_order", "valve", 0.35), ("friction_dynamics:lugre", "mechanics",
                                                          0.6)]
    found = place(prepared, ModelParams(), leads)
    replays = found["replays"]
    assert replays["mechanics"] is None and replays["valve_and_chambers"] is None
    assert max(e["removed"] for e in found["experiments"]) < PLACES
    assert found["subsystem"] == "mechanics"
    assert found["placed_by"] == "friction_dynamics:lugre" and "60 %" in found["words"]
    unplaced = by_candidates((), "no one measured signal explains it")
    assert unplaced["subsystem"] == "none" and "cannot place it" in unplaced["words"]


def test_with_one_pressure_the_motion_that_carries_the_error_places_it(tmp_path):
    """The load spring with chamber 1's pressure alone: the piston cannot be replayed (it is
    driven by both pressures), but fed the measured motion the valve and chamber 1 miss the
    measured pressure by a twentieth of what the whole model misses it by (0.16 % against
    4.04 %): the motion carried the error, so the mechanics, by elimination. (A wall heat
    exchange and a pressure-dependent valve gain, recorded so, keep gaps of their own on that
    replay, 14 % and 6.8 % against 6.7 % and 2.6 %, and stay in the chamber and the valve.)"""
    found = place(recorded(tmp_path, "load_spring", "one_pressure", stiffness=1e4),
                  ModelParams(), [("leakage:laminar", "chamber", 0.4)])
    replays = found["replays"]
    assert replays["mechanics"] is None and set(replays["valve_and_chambers"]) >= {"p1"}
    assert found["subsystem"] == "mechanics" and "by elimination" in found["words"]
    whole = float(found["words"].split("the whole model by ")[1].split(" %")[0])
    assert replays["valve_and_chambers"]["gap"] < min(0.5, 0.1 * whole)


@pytest.mark.parametrize("effect, values, subsystem", [
    ("pressure_dependent_gain", {"slope": 0.3}, "valve"),
    ("wall_heat_exchange", {"heat_transfer_coefficient": 30.0}, "chamber")])
def test_the_valve_and_the_chambers_are_told_apart_by_the_flow_map(tmp_path, effect, values,
                                                                   subsystem):
    """Both replay from the measured motion with a gap the mechanics has not. A valve whose
    flow gain moves 3 % per bar with the chamber pressure: Eq. 8 times a smooth gain, fitted
    afresh, removes most of the chambers' replay gap (valve). Gas exchanging heat with the walls
    (30 W/(m^2 K)) is no static map of command and pressure: it does not (chamber). One
    placement per case, so the two run side by side."""
    found = placed(tmp_path, effect, **values)
    replays = found["replays"]
    assert replays["valve_and_chambers"]["gap"] > 3 * replays["mechanics"]["gap"]
    assert found["subsystem"] == subsystem
    if subsystem == "valve":
        assert found["flow_map_removed"] > PLACES
    else:
        assert found["flow_map_removed"] < 0.25
