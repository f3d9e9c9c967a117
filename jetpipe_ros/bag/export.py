"""Convert a campaign bag into the dataset layout of docs/data.md (``jetpipe export``).

The ``id_recorder`` marks each experiment with an event on ``/id_recorder/events`` (name, first
sample's stamp, sample count, piston, role, load). For every complete experiment the export
takes, at each sample's stamp t_k (simulated time): y and v from ``joint_states``, p1 and p2
from the pressure topics, and u and f_load from ``voltage_applied`` stamped t_k+1 (the command
and the load held over [t_k, t_k+1); bags without the load joint: the event's constant load), so
row k follows the convention of :func:`jetpipe_ros.model.simulate`. A rig without one or both
chamber pressure sensors is exported as it was recorded: a pressure topic absent from the bag,
or without a message in an experiment's time span, leaves that column out of the experiment's
CSV (a position-only or one-pressure record, docs/data.md), and the export says so. Regulated
friction tests are marked ``regulated: true`` in ``dataset.yaml``, as ``jetpipe identify`` reads
them. A few samples lost in transport are interpolated and counted; more than
:data:`MAX_MISSING` of an experiment is an error.

A bag without campaign events (``id_recorder``'s ``mode: record`` beside a driver, or any
recorder of the contract's topics; a campaign's bag holds one from its first sample) is one
recording: it is written as one experiment, a row at
each ``joint_states`` stamp as the driver stamped it, the command from the ``voltage_applied``
that follows it; a stamp with no partner message in reach is a lost row, left out for the
dataset reader to fill, as it does any logger's (:mod:`jetpipe_ros.dataset.timebase`).

A bag that was never closed (its recorder killed: no ``metadata.yaml``, or an MCAP file without
footer) is read from its MCAP stream (:mod:`jetpipe_ros.bag.recover`), and the export says so:
the experiments whose end the recorder marked before it died are exported as usual.

The dataset directory is checked before the bag is read: it must be new or empty, or, with
``overwrite``, a dataset directory written before (never the bag, a directory holding it, or
the current directory; :func:`jetpipe_ros.dataset.dataset.check_target`).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader, ReaderError
from rosbags.typesys import get_typestore

from jetpipe_ros.bag.recover import StreamReport, stream_messages
from jetpipe_ros.bag.writer import EVENTS_TOPIC, TYPESTORE
from jetpipe_ros.dataset import DatasetError, Entry, write_dataset
from jetpipe_ros.dataset.dataset import check_target
from jetpipe_ros.dataset.timebase import fit_grid
from jetpipe_ros.topics import OPTIONAL_SENSORS, SENSOR_TOPICS

MAX_MISSING = 0.01  #: largest fraction of an experiment's samples that may be interpolated
#: Stamped topics read, by the suffix their (possibly namespaced) name ends with.
SIGNALS = (*SENSOR_TOPICS.values(), "voltage_applied")
#: Those a rig may lack (the pressure sensors), by the column they fill.
OPTIONAL = {key: SENSOR_TOPICS[key] for key in OPTIONAL_SENSORS}


class BagError(DatasetError):
    """A bag cannot be exported; the message names the bag and what is missing."""


def _find(bag: Path, names: list[str], suffix: str) -> str | None:
    """The one topic of ``names`` ending in ``suffix`` (None for an optional signal the bag
    lacks); BagError if there are several, or none of a required signal."""
    hits = [n for n in names if n == f"/{suffix}" or n.endswith(f"/{suffix}")]
    if len(hits) > 1 or (not hits and suffix not in OPTIONAL.values()):
        raise BagError(f"{bag}: expected one topic ending in {suffix!r}, found "
                       f"{hits or 'none'} (topics: {', '.join(sorted(names))})")
    return hits[0] if hits else None


def read_signals(bag: str | Path, progress: Callable[[str], None] = print
                 ) -> tuple[dict[str, dict[str, np.ndarray]], list[dict]]:
    """The stamped signals of a bag and its campaign events.

    Returns ({suffix: {"t": stamps [ns], field: values}}, events): for ``joint_states``
    the fields y [m] and v [m/s], for the pressures p [Pa], for ``voltage_applied`` u [V] and
    f_load [N] (NaN if the bag's simulator did not report it);
    duplicate stamps (a lock-step simulator re-publishing while it waits) are dropped.
    A bag that was not closed is read from its MCAP stream, saying so through ``progress``.
    """
    bag = Path(bag)
    if not bag.is_dir():
        raise BagError(f"{bag}: not a rosbag2 bag (no such directory)")
    mcaps = sorted(bag.glob("*.mcap"))
    if not (bag / "metadata.yaml").is_file():
        if not mcaps:
            raise BagError(f"{bag}: not a rosbag2 bag (no metadata.yaml, no .mcap file)")
        progress(f"{bag}: no metadata.yaml: the recording was not closed (recorder killed?); "
                 f"recovering it from the MCAP stream")
        return _recovered(bag, mcaps, progress)
    try:
        with Reader(bag) as reader:
            names = [c.topic for c in reader.connections]
            wanted = [c for c in reader.connections
                      if _suffix(c.topic) or c.topic == EVENTS_TOPIC]
            _topics(bag, names)  # before reading
            messages = ((c.topic, c.msgtype, raw)
                        for c, _, raw in reader.messages(connections=wanted))
            return _decode(bag, names, messages)
    except ReaderError as exc:
        if not mcaps:
            raise BagError(f"{bag}: unreadable bag: {exc}") from None
        progress(f"{bag}: unreadable as a closed bag ({exc}); recovering it from the MCAP "
                 f"stream")
        return _recovered(bag, mcaps, progress)


def _recovered(bag: Path, mcaps: list[Path], progress: Callable[[str], None]
               ) -> tuple[dict[str, dict[str, np.ndarray]], list[dict]]:
    """Read a bag that was not closed from its MCAP files' record streams."""
    names: list[str] = []  # the channels' topics, filled in while reading
    reports = [StreamReport(m, topics=names) for m in mcaps]

    def messages() -> Iterator[tuple[str, str, bytes]]:
        for path, report in zip(mcaps, reports):
            for topic, msgtype, _, raw in stream_messages(path, report):
                if _suffix(topic) or topic == EVENTS_TOPIC:
                    yield topic, msgtype, raw

    signals, events = _decode(bag, names, messages())
    for report in reports:
        progress(f"recovered {report.describe()}")
    return signals, events


def _suffix(topic: str) -> str | None:
    """The signal (one of :data:`SIGNALS`) whose name ``topic`` ends with, or None."""
    return next((s for s in SIGNALS if topic == f"/{s}" or topic.endswith(f"/{s}")), None)


def _topics(bag: Path, names: list[str]) -> dict[str, str]:
    """{topic: signal suffix} of the bag's topics ``names``; BagError if a required one is
    missing or one is ambiguous."""
    return {t: s for s in SIGNALS if (t := _find(bag, names, s)) is not None}


def _decode(bag: Path, names: list[str], messages: Iterator[tuple[str, str, bytes]]
            ) -> tuple[dict[str, dict[str, np.ndarray]], list[dict]]:
    """Signals and events from (topic, type, CDR) messages; ``names``: every topic of the bag
    (complete once ``messages`` is exhausted: a recovered bag's are found while reading)."""
    store = get_typestore(TYPESTORE)
    by_topic: dict[str, list[tuple[float, ...]]] = {}
    events = []
    for topic, msgtype, raw in messages:
        msg = store.deserialize_cdr(raw, msgtype)
        if topic == EVENTS_TOPIC:
            events.append(json.loads(msg.data))
            continue
        suffix = _suffix(topic)
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if suffix == "joint_states":
            row: tuple[float, ...] = (stamp, msg.position[0], msg.velocity[0])
        elif suffix == "voltage_applied":
            load = msg.effort[1] if len(msg.effort) > 1 else np.nan
            row = (stamp, msg.position[0], load)
        else:
            row = (stamp, msg.fluid_pressure)
        by_topic.setdefault(topic, []).append(row)
    topics = _topics(bag, names)
    rows = {s: by_topic.get(t, []) for t, s in topics.items()}
    fields = {"joint_states": ("y", "v"), "voltage_applied": ("u", "f_load"),
              "chamber1/pressure": ("p",), "chamber2/pressure": ("p",)}
    signals = {}
    for suffix, data in rows.items():
        arr = np.array(data, dtype=float).reshape(-1, 1 + len(fields[suffix]))
        stamps, first = np.unique(arr[:, 0].astype(np.int64), return_index=True)
        signals[suffix] = {"t": stamps, **{f: arr[first, i + 1]
                                           for i, f in enumerate(fields[suffix])}}
    return signals, events


def _within(sig: dict[str, np.ndarray] | None, stamps: np.ndarray) -> bool:
    """True if the signal ``sig`` (None: not in the bag) has a stamp within ``stamps``' span."""
    if sig is None:
        return False
    t = sig["t"]
    return bool(np.any((t >= stamps[0]) & (t <= stamps[-1])))


def _at(bag: Path, name: str, sig: dict[str, np.ndarray], key: str,
        stamps: np.ndarray) -> tuple[np.ndarray, int]:
    """Values of ``sig[key]`` at ``stamps`` [ns]; missing stamps interpolated; their count."""
    t = sig["t"]
    if t.size == 0 or stamps[0] < t[0] or stamps[-1] > t[-1]:
        raise BagError(f"{bag}: experiment {name}: signal {key} does not cover the "
                       f"experiment's time span")
    index = np.searchsorted(t, stamps)
    found = (index < t.size) & (t[np.minimum(index, t.size - 1)] == stamps)
    values = np.interp(stamps.astype(float), t.astype(float), sig[key])
    return values, int(np.count_nonzero(~found))


def export_bag(bag: str | Path, out_dir: str | Path, overwrite: bool = False,
               progress: Callable[[str], None] = print) -> Path:
    """Write the complete experiments of campaign bag ``bag`` as a dataset in ``out_dir``.

    Each CSV has ``t,u,y,p1,p2,v,f_load`` (without the pressures the rig did not measure);
    ``dataset.yaml`` has piston, load_force, role, kind and the number of interpolated samples
    (``missing_samples``). Written atomically.
    """
    bag = Path(bag)
    check_target(out_dir, overwrite, protect=[bag])
    signals, events = read_signals(bag, progress)
    experiments = [e for e in events if e.get("event") == "experiment"]
    if not events:
        progress(f"{bag}: no campaign events (recorded with mode: record, or by another "
                 f"recorder): the recording is written as one experiment")
        return write_dataset(out_dir, [_recording(bag, signals, progress)],
                             overwrite=overwrite, protect=[bag])
    complete = [e for e in experiments if e.get("complete")]
    for e in experiments:
        if not e.get("complete"):
            progress(f"skipping {e['name']}: interrupted after {e['samples']} samples")
    if not complete:
        raise BagError(f"{bag}: no complete experiment in the bag")
    out = []
    without: dict[str, list[str]] = {}  # experiments by the pressures their rig did not log
    for e in complete:
        name, n, dt_ns = e["name"], int(e["samples"]), int(round(e["dt"] * 1e9))
        stamps = int(e["start_ns"]) + dt_ns * np.arange(n, dtype=np.int64)
        cols: dict[str, np.ndarray] = {"t": np.arange(n) * e["dt"]}
        missing = 0
        unmeasured = [key for key, suffix in OPTIONAL.items()
                      if not _within(signals.get(suffix), stamps)]
        for key, suffix, at in (("u", "voltage_applied", stamps + dt_ns),
                                ("y", "joint_states", stamps),
                                ("p1", "chamber1/pressure", stamps),
                                ("p2", "chamber2/pressure", stamps),
                                ("v", "joint_states", stamps),
                                ("f_load", "voltage_applied", stamps + dt_ns)):
            if key in unmeasured:
                continue
            field = {"p1": "p", "p2": "p"}.get(key, key)
            cols[key], lost = _at(bag, name, signals[suffix], field, at)
            missing = max(missing, lost)
        if missing > MAX_MISSING * n:
            raise BagError(f"{bag}: experiment {name}: {missing} of {n} samples missing "
                           f"(more than {MAX_MISSING:.0%})")
        if not np.all(np.isfinite(cols["f_load"])):  # the simulator did not report its load
            cols["f_load"] = np.full(n, float(e["load_force"]))
        extra = {"kind": e["kind"], "missing_samples": missing}
        if e.get("regulated"):
            extra["regulated"] = True
        out.append((Entry(f"{name}.csv", piston="locked" if e["locked"] else "free",
                          load_force=float(e["load_force"]), role=e["role"], extra=extra),
                    cols))
        if unmeasured:
            without.setdefault(" and ".join(unmeasured), []).append(name)
        progress(f"{name}: {n} samples ({n * e['dt']:.1f} s), {missing} interpolated")
    for lacking, names in without.items():
        where = "every experiment" if len(names) == len(complete) else ", ".join(names)
        progress(f"{lacking} not measured (no message on the topic) in {where}: left out of "
                 f"the CSVs, read as a record without that sensor")
    return write_dataset(out_dir, out, overwrite=overwrite, protect=[bag])


def _recording(bag: Path, signals: dict[str, dict[str, np.ndarray]],
               progress: Callable[[str], None]) -> tuple[Entry, dict[str, np.ndarray]]:
    """A bag without campaign events as one experiment: a row at each ``joint_states`` stamp
    t_k (t from the first, as stamped: jitter and lost samples are the dataset reader's to
    snap and fill), u_k and the load from the ``voltage_applied`` stamped next (the command
    applied over [t_k, t_k+1)), each pressure from its message stamped nearest t_k. The sample
    time is the step of the regular grid nearest the stamps (the dataset reader's own fit,
    :func:`~jetpipe_ros.dataset.timebase.fit_grid`); a partner message further than half of it
    from where it belongs makes the row a lost one (left out, counted). The piston is taken as
    free and no role is set (the diagnosis then holds out the last 30 %): ``dataset.yaml`` says
    otherwise where the user knows better."""
    js, va = signals["joint_states"], signals["voltage_applied"]
    t = js["t"]
    if t.size < 3 or va["t"].size < 2:
        raise BagError(f"{bag}: too few joint_states ({t.size}) or voltage_applied "
                       f"({va['t'].size}) messages to make a record of")
    tau = (t - t[0]) * 1e-9  # [s] from the first stamp: absolute clocks lose digits
    dt = int(round(fit_grid(tau, float(np.median(np.diff(tau))))[1] * 1e9))  # [ns]

    def partner(sig: dict[str, np.ndarray], at: np.ndarray) -> np.ndarray:
        """Index of ``sig``'s message stamped nearest each of ``at``; -1 beyond dt / 2."""
        j = np.clip(np.searchsorted(sig["t"], at), 1, sig["t"].size - 1)
        j = np.where(np.abs(sig["t"][j - 1] - at) <= np.abs(sig["t"][j] - at), j - 1, j)
        return np.where(np.abs(sig["t"][j] - at) <= dt // 2, j, -1)

    # Where the command applied after each sample is stamped: the next sample's stamp, or one
    # sample time on where the next sample was lost.
    nxt = np.r_[t[1:], t[-1] + dt]
    nxt = np.where(nxt - t <= dt + dt // 2, nxt, t + dt)
    command = partner(va, nxt)
    keep = command >= 0
    keep[-1] = False  # the command after the last sample is not in the bag
    pressures = {key: partner(signals[suffix], t) for key, suffix in OPTIONAL.items()
                 if _within(signals.get(suffix), t) and signals[suffix]["t"].size > 1}
    for j in pressures.values():
        keep &= j >= 0
    rows = np.flatnonzero(keep)
    if rows.size < 3:
        raise BagError(f"{bag}: no joint_states sample has its voltage_applied and pressures "
                       f"within {dt / 2e6:g} ms: not a stream of the topic contract")
    cols = {"t": tau[rows] - tau[rows[0]], "u": va["u"][command[rows]],
            "y": js["y"][rows], "v": js["v"][rows]}
    for key, j in pressures.items():
        cols[key] = signals[OPTIONAL[key]]["p"][j[rows]]
    load = va["f_load"][command[rows]]
    if np.all(np.isfinite(load)):
        cols["f_load"] = load
    lacking = [k for k in OPTIONAL if k not in pressures]
    span = t[rows[-1]] - t[rows[0]]
    lost = int(round(span / dt)) + 1 - rows.size  # rows of the span the reader will fill
    progress(f"{bag.name}: {rows.size} rows at {dt / 1e6:g} ms ({span * 1e-9:.1f} s); {lost} "
             f"lost (missing from the stream, or without their partner messages)"
             + (f"; {' and '.join(lacking)} not measured (no message on the topic)"
                if lacking else "") + "; piston taken as free, no role set: say otherwise in "
             "dataset.yaml")
    return Entry(f"{bag.name}.csv", extra={"lost_samples": lost}), cols


def _run(args: argparse.Namespace) -> int:
    root = export_bag(args.bag, args.dataset_dir, overwrite=args.overwrite)
    print(f"dataset written to {root}")
    return 0


def add_command(subparsers) -> None:
    """``jetpipe export BAG DATASET_DIR``: a campaign bag to a dataset."""
    p = subparsers.add_parser(
        "export", help="convert an id_recorder campaign bag into a dataset (docs/data.md)",
        description="Read a rosbag2 (MCAP) bag recorded by id_recorder and write one CSV per "
                    "complete experiment (t,u,y,p1,p2,v,f_load; no column for a pressure the "
                    "rig did not publish) and dataset.yaml; a bag without campaign events "
                    "(mode: record, or another recorder of the topics) is one experiment.")
    p.add_argument("bag", help="bag directory (holds metadata.yaml and the .mcap file; a bag "
                               "whose recorder was killed is recovered from the .mcap file)")
    p.add_argument("dataset_dir", help="dataset directory to create")
    p.add_argument("--overwrite", action="store_true",
                   help="replace dataset_dir if it is a dataset written before (dataset.yaml "
                        "and the files it lists only; never the bag or the current directory)")
    p.set_defaults(func=_run)
