"""The twin core (jetpipe_ros.twin): the model following measured samples, its gap and levels."""

from __future__ import annotations

import numpy as np
import pytest

from jetpipe_ros.model import ModelParams
from jetpipe_ros.twin import Level, Settings, Twin
from jetpipe_ros.twin.gap import MIN_HISTORY, GapWindow, HorizonScore, bar
from jetpipe_ros.twin.stepper import line_end
from twin_data import hardware

LAG = {"effects.valve_lag.enabled": True, "effects.valve_lag.corner_frequency": 20.0}


def _levels(twin: Twin, rows: np.ndarray) -> dict[int, dict[str, tuple[Level, float, float]]]:
    """Per completed second: each judged signal's (level, gap %, z)."""
    out = {}
    for i in range(rows.shape[0]):
        twin.feed(*rows[i])
        if (i + 1) % 1000 == 0:
            out[(i + 1) // 1000] = {g.signal: (g.level, g.gap, g.z) for g in twin.judged}
    return out


def test_line_end_recovers_value_and_slope_of_a_line():
    t = np.arange(21) * 1e-3
    value, slope = line_end(t, 0.01 + 0.2 * t)
    assert value == pytest.approx(0.01 + 0.2 * 0.020)
    assert slope == pytest.approx(0.2)
    assert line_end(t[:2], np.array([1.0, 2.0])) == (2.0, 0.0)


def test_nominal_model_on_nominal_hardware_is_ok_and_predicts_closely():
    rows = hardware(ModelParams(), 14.0)
    twin = Twin(ModelParams())
    levels = _levels(twin, rows)
    judged = {s: v for s, v in levels.items() if v}
    assert min(judged) == MIN_HISTORY + 1  # horizons 0-1 ... 5-6 s: judged from 6 s on
    for second, signals in judged.items():
        assert set(signals) == {"y", "p1", "p2"}
        for signal, (level, gap, z) in signals.items():
            assert level == Level.OK, (second, signal, gap, z)
            assert abs(z) < 3.0 and gap < 1.5
    # What noise explains is what the sensors' noise is: 15 um on y, 500 Pa on p over spreads
    # of several mm and tenths of bar; the model explains the rest.
    for g in twin.judged:
        assert g.mse == pytest.approx(g.floor, rel=0.1)
    y = next(g for g in twin.judged if g.signal == "y")
    assert 15e-6 / y.scale < np.sqrt(y.floor) < 3 * 15e-6 / y.scale
    assert twin.counters.samples == 14000 and twin.counters.horizons == 13


def test_valve_lag_in_the_hardware_is_an_error_on_every_signal():
    rows = hardware(ModelParams().with_effect("valve_lag", corner_frequency=20.0), 7.0)
    twin = Twin(ModelParams())
    levels = _levels(twin, rows)
    assert levels[6] == {s: (Level.ERROR, pytest.approx(levels[6][s][1]),
                             pytest.approx(levels[6][s][2])) for s in ("y", "p1", "p2")}
    for level, gap, z in levels[6].values():
        assert gap > 3.0 and z > 30.0


def test_effect_switched_on_mid_run_is_flagged_within_two_horizons():
    rows = hardware(ModelParams(), 14.0, switch=(10.0, LAG))
    levels = _levels(Twin(ModelParams()), rows)
    for second in range(6, 11):
        assert {lv for lv, _, _ in levels[second].values()} == {Level.OK}, second
    first_error = min(s for s, v in levels.items()
                      if any(lv == Level.ERROR for lv, _, _ in v.values()))
    assert first_error <= 12
    assert all(lv == Level.ERROR for lv, _, _ in levels[14].values())


def test_the_level_says_since_which_sample_it_holds():
    """The stamp of the last sample of the horizon whose judgement set the level: the end of
    the first judged horizon (4.999 s, OK: five horizons scored) until a 20 Hz lag switched on at 10 s turns it to
    ERROR at the end of a horizon after the switch, in the stream's own time."""
    rows = hardware(ModelParams(), 14.0, switch=(10.0, LAG))
    twin = Twin(ModelParams())
    since = {}
    for i in range(rows.shape[0]):
        twin.feed(*rows[i])
        if twin.level_since is not None:
            since.setdefault(twin.level, twin.level_since)
    assert since[Level.OK] == pytest.approx(4.999)
    assert twin.level == Level.ERROR
    assert min(abs(since[Level.ERROR] - t) for t in (10.999, 11.999)) < 1e-9
    assert twin.level_held() == pytest.approx(13.999 - since[Level.ERROR])


def test_the_augmented_model_matches_the_lagging_hardware():
    lagging = ModelParams().with_effect("valve_lag", corner_frequency=20.0)
    levels = _levels(Twin(lagging), hardware(lagging, 7.0))
    assert {lv for lv, _, _ in levels[7].values()} == {Level.OK}


def test_gaps_in_the_measurements_fill_pause_and_drop():
    rows = hardware(ModelParams(), 9.0)
    keep = np.ones(rows.shape[0], dtype=bool)
    keep[3000:3005] = False  # 5 ms lost: filled, never compared
    keep[5500:5700] = False  # 0.2 s lost: the comparison pauses and restarts
    data = rows[keep]
    data = np.insert(data, 100, data[99], axis=0)  # a repeated stamp: dropped
    twin = Twin(ModelParams())
    pred = twin.feed(*data.T)
    c = twin.counters
    assert (c.late, c.filled, c.paused) == (1, 5, 1)
    assert c.paused_s == pytest.approx(0.2)
    assert c.samples == 9000 - 205
    after = np.flatnonzero(data[:, 0] == rows[5700, 0])[0]
    # Predicted: every sample but the first of each segment (nothing steps into it) and the
    # repeated stamp.
    unpredicted = np.flatnonzero(~np.isfinite(pred).all(axis=1))
    assert unpredicted.tolist() == [0, 100, after]
    # 0-5.5 s: five whole horizons and one of 0.5 s; 5.7-9 s: three of 1, 1 and 1.3 s ... as
    # far as they went: 5.7-6.7, 6.7-7.7, 7.7-8.7 closed (8.7-9 s still open)
    assert c.horizons == 6 + 3
    assert {g.level for g in twin.judged} == {Level.OK}
    assert twin.paused_since is None


def test_a_right_model_is_flagged_at_the_normal_law_s_rate_however_short_the_history():
    """Under a right model a horizon's three scores (data, two noisy copies) are draws of one
    law; the gap's standard error is measured on the k horizons held, so the excess over it is
    Student t with k degrees of freedom. The bar keeps the false-alarm rate at that of 3
    standard errors of a normal law, 0.135 %, from the first judgement (k = 5, where a flat bar
    of 3 raises 1.5 %) to a full history."""
    rng = np.random.default_rng(3)
    count, trials = 1000, 20000
    for k in (MIN_HISTORY, 12):
        alarms = flat = 0
        for _ in range(trials):
            gaps = GapWindow(window=5, history=30)
            sse = rng.chisquare(count, (k, 3)) * 1e-6  # 1 mm^2 per sample: a 1 mm noise
            for a, b, c in sse:
                gaps.add("y", HorizonScore(a, b, c, count, count, 0.0, count * 1e-4))
            (g,) = gaps.judge()
            alarms += g.z >= g.bar
            flat += g.z >= 3.0
        # 27 alarms expected (binomial sd 5); a flat bar of 3: 300 at k = 5, 150 at k = 12.
        assert 10 <= alarms <= 50, (k, alarms)
        assert flat > 100, (k, flat)
    assert bar(5) == pytest.approx(5.51, abs=0.01) and bar(30) == pytest.approx(3.27, abs=0.01)


def test_bad_settings_name_the_setting():
    with pytest.raises(ValueError, match="twin setting warmup"):
        Settings(warmup=2.0)


def test_capture_keeps_the_latest_samples_and_writes_them_as_a_dataset(tmp_path):
    from jetpipe_ros.dataset import read_dataset
    from jetpipe_ros.twin.capture import Recent, write_capture

    rows = hardware(ModelParams(), 12.0)
    recent = Recent(9.0, 0.001)
    for row in rows:
        recent.add(row)
    kept = recent.snapshot()
    assert np.array_equal(kept, rows[-9000:])
    kept[100, 4] = np.nan  # a pressure message lost: that row is left out
    write_capture(kept, tmp_path / "ds")
    ds = read_dataset(tmp_path / "ds")
    assert [e.role for e, _ in ds] == ["train", "train", "holdout"]
    assert ds.entries[0].extra["received_rows"] == 9000
    assert ds.entries[0].extra["incomplete_rows"] == 1
    first = ds.experiments[0]
    # Row k: the measurements at t_k with the command applied over [t_k, t_k+1), which the
    # received rows carry on the next stamp.
    assert first.y[:100] == pytest.approx(rows[3000:3100, 3], rel=1e-8)
    assert first.u[:100] == pytest.approx(rows[3001:3101, 1], rel=1e-8, abs=1e-12)
    # 8,999 rows with a command, 8,998 of them whole; the reader fills the one left out.
    assert [exp.t.size for _, exp in ds] == [3000, 2999, 3000]
    assert np.flatnonzero(~first.valid).tolist() == [100]


def test_a_capture_holds_the_last_seconds_of_a_stream_that_lost_samples():
    """A monitor that lost every tenth sample holds 9,000 rows over 10 s: the capture of the
    last 9 s keeps the 8,100 rows received in them, not rows from before (which, on a loaded
    machine, had reached back to before an effect was switched on)."""
    from jetpipe_ros.twin.capture import Recent

    rows = hardware(ModelParams(), 12.0)
    received = rows[np.arange(rows.shape[0]) % 10 != 5]
    recent = Recent(9.0, 0.001)
    for row in received:
        recent.add(row)
    kept = recent.snapshot()
    assert np.array_equal(kept, received[received[:, 0] > 11.999 - 9.0 + 5e-4])
    assert kept.shape[0] == 8100 and kept[0, 0] == pytest.approx(3.0)


def test_a_sample_never_received_leaves_the_row_before_it_without_a_command(tmp_path):
    """A monitor that lost a whole sample (its command too) holds rows k-1 and k+1 side by side;
    row k-1's command is the one received with sample k, so row k-1 has none: it is left out
    with the lost one, never paired with sample k+1's command (which a one-row shift gave)."""
    from jetpipe_ros.dataset import read_dataset
    from jetpipe_ros.twin.capture import write_capture

    rows = hardware(ModelParams(), 9.0)
    received = np.delete(rows, 1200, axis=0)
    write_capture(received, tmp_path / "ds")
    ds = read_dataset(tmp_path / "ds")
    assert ds.entries[0].extra["incomplete_rows"] == 1  # 8,999 received, 8,997 whole
    first = ds.experiments[0]
    assert np.flatnonzero(~first.valid).tolist() == [1199, 1200]
    n, kept = first.t.size, first.valid
    assert first.u[kept] == pytest.approx(rows[1:n + 1, 1][kept], rel=1e-8, abs=1e-12)
    assert first.y[kept] == pytest.approx(rows[:n, 3][kept], rel=1e-8)


def test_hardware_with_the_position_alone_is_followed_judged_and_captured(tmp_path):
    """A rig without pressure sensors: the twin simulates both chambers, judges the position
    alone, and flags a 20 Hz valve lag there from its second judgement on (ERROR, gaps
    4.5-6.9 %, z 14-32; the same run with the pressures measured: the position's gaps alike,
    its z 63-267, the pressures restarting the chambers). Its capture has the position as its
    only sensor column and every row, where a capture that expected the pressures would have
    none, and says so."""
    from jetpipe_ros.dataset import DatasetError, read_dataset
    from jetpipe_ros.twin.capture import write_capture

    rows = hardware(ModelParams().with_effect("valve_lag", corner_frequency=20.0), 10.0)
    rows[:, 4:6] = np.nan
    levels = _levels(Twin(ModelParams()), rows)
    for second in range(7, 11):
        assert set(levels[second]) == {"y"}
        level, gap, z = levels[second]["y"]
        assert level == Level.ERROR and gap > 3.0 and z > 10.0, (second, gap, z)
    write_capture(rows, tmp_path / "ds", sensors=("y",))
    ds = read_dataset(tmp_path / "ds")
    assert sum(exp.t.size for _, exp in ds) == rows.shape[0] - 1
    assert all(exp.p1 is None and exp.p2 is None for _, exp in ds)
    assert ds.experiments[0].y[:50] == pytest.approx(rows[:50, 3], rel=1e-8)
    with pytest.raises(DatasetError, match=r"0 of the 10000 rows .* \(y, p1, p2\) finite"):
        write_capture(rows, tmp_path / "expected_pressures")
    assert not (tmp_path / "expected_pressures").exists()


@pytest.mark.parametrize("start", [(2.0e5, 8.0e5), (9.0e5, 1.5e5)])
def test_an_unmeasured_chamber_is_compared_once_its_start_no_longer_matters(start):
    """Position-only hardware that is the model itself, its chambers starting at 2 and 8 bar
    (9 and 1.5) where the model assumes 4.2: nothing is compared until the model from
    atmosphere and from supply hold both chambers within the pressure sensor's 500 Pa, then
    every judgement is OK. Compared from the start, the first two judgements were ERROR
    (position gaps of 92 % and 4 %; 155 % and 3 %): the model's chambers were where it
    assumed, not the hardware's."""
    p0 = {"chamber.initial_pressure_1": start[0], "chamber.initial_pressure_2": start[1]}
    rows = hardware(ModelParams().with_values(p0), 12.0)
    rows[:, 4:6] = np.nan
    twin = Twin(ModelParams())
    levels = _levels(twin, rows[:1000])
    assert twin.settling_since == 0.0 and twin.counters.horizons == 0 and not levels[1]
    levels.update(_levels(twin, rows[1000:]))
    assert twin.settling_since is None and 0.2 < twin.counters.unsettled_s < 5.0
    judged = {second: v for second, v in levels.items() if v}
    assert judged and min(judged) <= 10
    for second, signals in judged.items():
        assert signals["y"][0] == Level.OK, (second, signals)


def test_stamps_at_another_rate_than_the_sample_time_are_said():
    """The median stamp interval is the hardware's sample time: a 500 Hz stream fed to a twin
    set to 1 kHz is said (2 ms against 1 ms), and so is a 1.25 ms stream, which the rounding
    of each interval to whole samples would run 25 % fast; a 1 kHz stream that lost 1 % of its
    samples and whose stamps jitter by +-0.3 of a sample is not (its median within 2 %)."""
    rows = hardware(ModelParams(), 2.0)
    slow = Twin(ModelParams())
    slow.feed(*rows[::2].T)
    assert slow.interval() == pytest.approx(2e-3)
    assert "every 2 ms, but sample_time is 1 ms: set it to the hardware's, 0.002 s" in \
        slow.rate_mismatch()
    odd = Twin(ModelParams())
    odd.feed(rows[:, 0] * 1.25, *rows[:, 1:].T)
    assert odd.interval() == pytest.approx(1.25e-3) and "every 1.25 ms" in odd.rate_mismatch()
    rng = np.random.default_rng(3)
    kept = np.sort(rng.choice(rows.shape[0], int(0.99 * rows.shape[0]), replace=False))
    lossy = rows[kept].copy()
    lossy[:, 0] += rng.uniform(-0.3e-3, 0.3e-3, kept.size)
    jittered = Twin(ModelParams())
    jittered.feed(*lossy.T)
    assert jittered.interval() == pytest.approx(1e-3, rel=0.02)
    assert jittered.rate_mismatch() is None
