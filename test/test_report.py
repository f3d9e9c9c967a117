"""The report's summary in words, from a stored diagnosis (no fitting): a measured seal's
pre-sliding friction named on a gap under the 0.5 % bar (self-check seed 6733, case 6, the
plant written apart from the model)."""

import gzip
import json
from pathlib import Path

from jetpipe_ros.workflows.report import summary
from test_diagnosis import assert_schema

STORED = Path(__file__).parent / "data" / "diagnoses" / "small_seal_friction.json.gz"


def test_a_small_named_effect_is_called_small_and_not_also_invisible(tmp_path):
    path = tmp_path / "diagnosis.json"
    path.write_bytes(gzip.decompress(STORED.read_bytes()))
    result = assert_schema(path)
    assert result["verdict"]["effect"] == "friction_dynamics"
    assert "friction_dynamics:lugre" in result["visibility"]["too_small_to_see"]
    text = summary(result)
    # The reason keeps the candidate's spelling (not "Friction_dynamics:lugre").
    assert "<p>friction_dynamics:lugre removes 46% of the held-out gap" in \
        text.replace("</p><p>", "<p>")
    assert "a small gap (under the 0.5 % at which it shows" in text
    # The named effect is not in the list of what the data cannot tell: its own sentence.
    invisible = text.split("would not show in these experiments (the data cannot tell): ")[1]
    assert invisible.split(".")[0] == "<code>moving_mass</code>"
    assert "the named effect (<code>friction_dynamics:lugre</code>, " \
           "<code>friction_dynamics:maxwell_slip</code>) would not show" in text


def test_a_ranking_rows_calibration_knobs_are_folded_away():
    """The ranking table shows each candidate's own parameters; the ten calibration knobs
    fitted beside them fold into a <details> (they had filled a column wider than the page)."""
    from jetpipe_ros.workflows.report import _cell, _params_cell
    result = json.loads(gzip.decompress(STORED.read_bytes()))
    row = next(r for r in result["ranking"] if "calibration" in r["params"])
    cell = _cell(_params_cell(row["params"]))
    inner = cell.removeprefix("<div class='params'>").removesuffix("</div>")
    shown, folded = inner.split("<details><summary>calibration</summary>")
    # one effect: its knobs by their own names (the row names the effect)
    effect = row["effects"][0]
    assert shown.split("=")[0] in row["params"][effect] and "calibration" not in shown
    assert folded.endswith("</details>") and folded.count("=") == len(
        row["params"]["calibration"])


def test_what_is_not_ruled_out_says_which_pressure_sensor_would_tell_it():
    """A `none` that cannot rule out effects the recalibration imitates on a position-only
    record: the summary names the pressure sensor that would tell each (what the imitation
    leaves with it logged is above the 0.5 % bar), and for one no sensor would, another record."""
    result = json.loads(gzip.decompress(STORED.read_bytes()))
    row = {"signature_gap_pct": 1.0, "left_gap_pct": 0.2, "imitated": True, "knobs": {}}
    result["visibility"]["not_ruled_out"] = ["thermal", "valve_delay", "valve_lag"]
    result["visibility"]["imitated_by_recalibration"] = {
        "valve_delay": {**row, "with_sensors": {"p1": 2.02, "p2": 0.31, "p1+p2": 2.3}},
        "thermal:polytropic": {**row, "with_sensors": {"p1": 0.2, "p2": 0.3, "p1+p2": 0.7}},
        "valve_lag:first_order": {**row, "with_sensors": {"p1": 0.2, "p2": 0.3, "p1+p2": 0.4}}}
    text = summary(result)
    said = text.split("<b>Not ruled out</b>")[1].split("</p>")[0]
    assert "logged with chamber 1's pressure as well, these experiments would tell " \
           "<code>valve_delay</code>" in said
    assert "logged with both pressures as well, these experiments would tell " \
           "<code>thermal</code>" in said
    assert said.endswith("a record with another sensor or experiment is needed to tell "
                         "<code>valve_lag</code>.")


def test_an_ambiguous_verdict_on_fewer_sensors_names_the_pressure_that_would_tell():
    """Two readings the records cannot tell apart, on a bench without pressure sensors: the
    summary names the pressure whose predictions differ by more than one reading's noise on the
    dataset's own experiments, and not the one that differs by less."""
    result = json.loads(gzip.decompress(STORED.read_bytes()))
    result["verdict"]["ambiguous_with"] = "valve_delay"
    result["verdict"]["separating_experiment"] = {
        "experiment": "square_3V_0p97Hz", "in_dataset": True, "designed": False,
        "difference_over_noise": 3.3, "with_sensors": {"p1": 4.2, "p2": 0.5}}
    said = summary(result).split("But <code>valve_delay</code>")[1].split("</p>")[0]
    assert said.endswith("Logged with chamber 1's pressure, these very experiments would tell "
                         "them apart too: the two models' predictions of it differ by 4.2 x a "
                         "pressure sensor's noise.")


def test_a_none_says_no_effect_once_and_what_it_cannot_rule_out_below():
    """The headline of a `none` after recalibration: "no unmodelled effect" once (the reason
    began with it too), and what the answer cannot rule out only in its own paragraph, with the
    sensor that would tell, not also as the reason's long tail."""
    from jetpipe_ros.diagnosis.diagnose import NOT_RULED_OUT
    from jetpipe_ros.diagnosis.verdict import NO_EFFECT

    result = json.loads(gzip.decompress(STORED.read_bytes()))
    result["verdict"].update(effect="none", effects=[], params={}, stderr={},
                             reason=f"{NO_EFFECT}the nominal parameters are off (x); "
                                    f"recalibrated, the held-out gap shrinks from 4.73 % to "
                                    f"0.17 %; {NOT_RULED_OUT}valve_delay: at its typical size")
    row = {"signature_gap_pct": 1.0, "left_gap_pct": 0.2, "imitated": True, "knobs": {},
           "with_sensors": {"p1": 2.0, "p2": 1.9, "p1+p2": 2.2}}
    result["visibility"].update(not_ruled_out=["valve_delay"],
                                imitated_by_recalibration={"valve_delay": row})
    text = summary(result)
    head = text.split("</p>")[0]
    assert head.endswith("<b>No unmodelled effect identified:</b> the nominal parameters are "
                         "off (x); recalibrated, the held-out gap shrinks from 4.73 % to "
                         "0.17 %.")
    assert text.lower().count("no unmodelled effect") == 1
    assert text.count("valve_delay") == 2  # "Not ruled out" and the sensor that would tell


def test_a_candidate_the_records_as_a_whole_favour_is_said_apart_with_the_record_to_add():
    """A `none` on a position-only record of a drooping supply (development seed 8951, case
    10): the supply line fits the training records better than the recalibration, not the
    held-out ones, and fitted on every record it leaves a quarter of what the recalibration
    leaves (jetpipe_ros.diagnosis.pooled). The headline keeps the answer; the candidate is said
    once, in its own paragraph, with its figures and the held-out record that would decide it;
    the command line says it too."""
    from jetpipe_ros.diagnosis.pooled import words
    from jetpipe_ros.diagnosis.verdict import NO_EFFECT
    from jetpipe_ros.workflows.cli import summary_lines

    result = json.loads(gzip.decompress(STORED.read_bytes()))
    row = {"candidate": "supply_pressure:line", "effect": "supply_pressure",
           "train_gap": 0.0956, "holdout_gap": 0.4636, "recalibration_train_gap": 0.2597,
           "recalibration_holdout_gap": 0.4941, "pooled_gap": 0.0677,
           "recalibration_pooled_gap": 0.2831, "pooled_shrinkage": 0.76, "pooled_t": 3.32,
           "favoured": True, "params": {"pressure": 7.51e5},
           "decisive_record": "square_3V_0p97Hz"}
    result["verdict"].update(effect="none", effects=[], params={}, stderr={},
                             reason=f"{NO_EFFECT}the nominal parameters are off (x); "
                                    f"recalibrated, the held-out gap shrinks from 3.94 % to "
                                    f"0.49 %; {words([row])}")
    result["visibility"].update(not_ruled_out=["supply_pressure"], imitated_by_recalibration={},
                                favoured_by_all_records=[row])
    result["visibility"].pop("smallest_shown", None)
    text = summary(result)
    assert text.split("</p>")[0].endswith("shrinks from 3.94 % to 0.49 %.")
    said = text.split("<b>Not ruled out</b> either: ")[1].split("</p>")[0]
    assert said.startswith("<code>supply_pressure:line</code>, which the records as a whole "
                           "favour. Fitted on every record, training and held-out, it leaves "
                           "0.07 % where the recalibration leaves 0.28 %.")
    assert "0.10 % of them (the recalibration 0.26 %) but 0.46 % held out (the " \
           "recalibration 0.49 %)" in said
    assert said.endswith("A training record like <code>square_3V_0p97Hz</code> would decide "
                         "it.")
    assert text.count("supply_pressure:line") == 1
    row["by_record"] = [{"record": "square_3V_0p97Hz", "recalibration": 0.71,
                         "recalibration_pooled": 0.40, "trained": 0.73, "pooled": 0.11},
                        {"record": "sweep_0p8V", "recalibration": 0.18,
                         "recalibration_pooled": 0.15, "trained": 0.15, "pooled": 0.04}]
    from jetpipe_ros.workflows.report import favoured_figure
    assert favoured_figure(row).startswith("<img")
    assert "cannot rule out supply_pressure: the records as a whole favour it, the held-out " \
           "ones cannot confirm it; a training record like 'square_3V_0p97Hz' would decide " \
           "it" in summary_lines(result, "out")


def test_a_named_port_is_told_as_a_catalogue_gives_it_with_its_time_constant():
    """A named port told by its volume, its restriction in a catalogue's units (1e-8
    m^3/(s Pa) = 1 dm^3/(s bar)), what its index makes of it against two standard errors (the
    port of held-out seed 5591 was fitted at m = 1 +- 0.016), and the time constant at rest
    worked by hand in test_port (40 cm^3 behind 0.3 dm^3/(s bar) at m = 0.5: 3.0 ms)."""
    from jetpipe_ros.workflows.report import port_words

    verdict = {"effect": "valve_lag", "effects": ["valve_lag"], "forms": {"valve_lag": "port"},
               "params": {"port_volume": 4e-5, "port_conductance": 3e-9, "port_index": 0.5},
               "stderr": {"valve_lag": {"port_index": 0.016}}}
    said = port_words(verdict)
    assert said.startswith("The port found: 40.0 cm^3 before each chamber behind a restriction "
                           "of sonic conductance 0.3 dm^3/(s bar) (ISO 6358) and subsonic "
                           "index m = 0.50 +- 0.02: an orifice or a fitting")
    assert said.endswith("a time constant of 3.0 ms.")
    verdict["params"]["port_index"] = 1.0
    assert "a porous element such as a sintered filter" in port_words(verdict)
    verdict["stderr"]["valve_lag"]["port_index"] = 0.28
    verdict["params"]["port_index"] = 0.72
    assert "the records do not tell an orifice (m = 0.5) from a porous element (m = 1)" in \
        port_words(verdict)
    verdict["stderr"]["valve_lag"]["port_index"] = 0.05
    assert "between an orifice (m = 0.5) and a porous element (m = 1)" in port_words(verdict)
    assert port_words({**verdict, "forms": {"valve_lag": "first_order"}}) is None


def test_a_named_hysteresis_loop_is_told_as_its_plays_not_its_knobs():
    """spread 0.5, sharp_share -0.6, half-width 0.25 V, eight plays (worked by hand): offsets
    +-0.125..0.875, shapes 0.5625..1.4375 (sum 8); weights 0.05 each and 0.65 for the widest, so
    weights . shapes = 0.4 + 0.6 x 1.4375 = 1.2625 and r = 0.25 shape / 1.2625: 0.1114 V to
    0.2847 V, the next widest 0.2599 V. A pair's hysteresis is told the same way."""
    from jetpipe_ros.workflows.report import loop_words
    values = {"half_width": 0.25, "spread": 0.5, "sharp_share": -0.6}
    text = loop_words({"effects": ["valve_hysteresis"], "params": values})
    assert "8 play operators with thresholds from 0.111 to 0.285 V (weighted mean 0.250 V" \
        in text
    assert "its widest play (0.285 V) holds 65 % of the loop, the other 7 (0.111 to 0.260 V) " \
           "5 % each" in text
    paired = loop_words({"effects": ["valve_lag", "valve_hysteresis"],
                         "params": {"valve_lag": {"corner_frequency": 20.0},
                                    "valve_hysteresis": {**values, "sharp_share": 0.6}}})
    assert "its narrowest play (0." in paired and "holds 65 % of the loop" in paired
    assert loop_words({"effects": ["valve_hysteresis"],
                       "params": {**values, "spread": 0.0}}) == \
        "The hysteresis loop found: 8 play operators at one threshold, 0.250 V: one sharp loop."
    assert loop_words({"effects": ["valve_lag"], "params": {"corner_frequency": 20.0}}) is None
