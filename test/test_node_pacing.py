"""Pacer: samples due per timer tick from elapsed wall time (no ROS needed)."""

from __future__ import annotations

import pytest

from jetpipe_ros.nodes.pacing import Pacer


def test_steps_by_elapsed_time_not_by_ticks():
    pacer = Pacer(dt=0.001, rate=1.0, max_batch=50, now=0.0)
    assert pacer.due(0.0005) == 0
    assert pacer.due(0.001) == 1
    assert pacer.due(0.0045) == 3  # two ticks missed: caught up
    assert pacer.due(0.0046) == 0
    assert (pacer.issued, pacer.largest, pacer.overruns) == (4, 3, 0)


def test_backlog_beyond_cap_is_dropped_and_counted():
    pacer = Pacer(dt=0.001, rate=1.0, max_batch=50, now=0.0)
    assert pacer.due(0.2) == 50
    assert (pacer.overruns, pacer.dropped) == (1, 150)
    assert pacer.due(0.201) == 1  # back on schedule, not catching up the dropped samples


def test_real_time_factor_and_flat_out():
    pacer = Pacer(dt=0.001, rate=5.0, max_batch=50, now=0.0)
    assert pacer.due(0.001) == 5
    pacer.set_rate(0.0, now=0.001)
    assert pacer.due(0.001) == 50 and pacer.due(0.001) == 50
    pacer.set_rate(2.0, now=1.0)
    assert pacer.due(1.01) == 20
    assert pacer.issued == 125
    assert pacer.ticks == 4


def test_bad_pacing_refused():
    with pytest.raises(ValueError):
        Pacer(dt=0.0, rate=1.0, max_batch=50, now=0.0)
    with pytest.raises(ValueError):
        Pacer(dt=0.001, rate=1.0, max_batch=50, now=0.0).set_rate(-1.0, now=0.0)
