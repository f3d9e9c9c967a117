"""An identification campaign: the experiments of ``config/campaign.yaml`` and their schedule.

The YAML file::

    sample_time: 0.001          # [s]
    settle:                     # before every experiment, not part of it
      center: 0.5               # [s] closed loop to y = 0 (skipped while the piston is locked)
      rest: 0.5                 # [s] 0 V with the experiment's piston state: valve at rest,
                                #     pressures back towards equilibrium
    experiments:
      - name: charge_0p29V      # file name of the experiment in the dataset
        kind: open_loop         # open_loop: the signal is the valve voltage [V]
        locked: true            # piston clamped (constant-volume test, Sec. 2.3)
        role: train             # train | holdout
        duration: 6.2           # [s]
        voltage: {signal: steps, levels: [0.29, -0.29], durations: [4.4, 1.8]}
      - name: stick_slip
        kind: closed_loop       # the controller closes the loop on position
        locked: false
        role: train
        duration: 6.0
        setpoint: {signal: triangle, amplitude: 0.002, frequency: 0.125}   # [m]
        excitation: {signal: hold, level: 0.0}   # [V] added to the controller output, optional
        load_force: 0.0         # [N] constant external load, optional
      - name: friction_1_6p93bar
        kind: open_loop         # the valve is irrelevant: voltage optional (default 0 V)
        role: train
        duration: 1.5
        regulated: {p1: 1.0e+5, p2: 6.93e+5}  # [Pa] chamber pressures held by regulators
        load: {signal: release, rate: 1000.0}  # [N] per sample; release starts at S (p1 - p2)

A ``regulated`` experiment is the friction test of the paper's Fig. 15 (Sec. 4.2): the rig
switches the chambers to regulators holding p1, p2 (``chamber.regulated``), places the piston at
rest at the end stop it leaves (the outer one, y = +stroke/2, for the entry phase p2 > p1; the
inner one for the exit phase) and holds it there with the hydraulic load ``load`` [N], which
starts at S (p1 - p2) (``release`` without ``level``; S, the stroke: the nominal values of
docs/model.md) and is then released. Its settle phase keeps the piston at the stop under the
initial load. ``load`` (a per-sample external load [N]) may also drive other open-loop
experiments, instead of the constant ``load_force``.

Signals name a generator of :mod:`jetpipe_ros.campaign.signals` and give its arguments (all
but ``dt`` and ``duration``). Loading checks everything and raises :class:`CampaignError`
naming the file, the experiment and the field.

:meth:`Campaign.schedule` turns the plan into the phases a runner executes in order: settle
phases and experiments. The offline runner and the ``id_recorder`` node both follow it.
"""

from __future__ import annotations

import inspect
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from jetpipe_ros.campaign.errors import CampaignError
from jetpipe_ros.campaign.signals import GENERATORS, samples
from jetpipe_ros.fileio import read_yaml
from jetpipe_ros.model.params import SPECS
from jetpipe_ros.package_data import share_file

#: Nominal piston area S [m^2] and half stroke [m] (docs/model.md): the regulated rig's
#: initial load S (p1 - p2) and the end stops it places the piston at.
AREA = float(SPECS["chamber.piston_area"].default)
HALF_STROKE = 0.5 * float(SPECS["mechanics.stroke"].default)
#: Range of a regulated chamber pressure [Pa, absolute] (the model's initial-pressure range).
PRESSURE_RANGE = (SPECS["chamber.initial_pressure_1"].low,
                  SPECS["chamber.initial_pressure_1"].high)

KINDS = ("open_loop", "closed_loop")
ROLES = ("train", "holdout")
NAME = re.compile(r"^[A-Za-z0-9_.-]+$")


@dataclass(frozen=True)
class SignalSpec:
    """A generator of :data:`~jetpipe_ros.campaign.signals.GENERATORS` and its arguments."""

    signal: str
    args: Mapping[str, Any] = field(default_factory=dict)

    def sample(self, dt: float, duration: float) -> np.ndarray:
        """The signal sampled every ``dt`` [s] over ``duration`` [s]."""
        return GENERATORS[self.signal](dt, duration, **self.args)

    def to_yaml(self) -> dict[str, Any]:
        """The spec as a campaign YAML mapping."""
        return {"signal": self.signal, **self.args}


@dataclass(frozen=True)
class Command:
    """What drives one experiment or phase, one value per sample.

    Open loop: ``voltage`` [V] and optionally ``load`` [N] (None: the phase's constant
    ``load_force``). Closed loop: ``setpoint`` [m] for the controller and ``excitation`` [V]
    added to its output.
    """

    voltage: np.ndarray | None = None
    setpoint: np.ndarray | None = None
    excitation: np.ndarray | None = None
    load: np.ndarray | None = None

    @property
    def closed_loop(self) -> bool:
        """True when the controller closes the loop."""
        return self.setpoint is not None

    def __len__(self) -> int:
        ref = self.setpoint if self.closed_loop else self.voltage
        assert ref is not None
        return int(ref.shape[0])


@dataclass(frozen=True)
class ExperimentSpec:
    """One experiment of a campaign (see the module docstring for the fields)."""

    name: str
    kind: str  #: open_loop | closed_loop
    duration: float  #: [s]
    locked: bool  #: piston clamped
    role: str  #: train | holdout
    voltage: SignalSpec | None = None  #: open loop: the valve voltage [V]
    setpoint: SignalSpec | None = None  #: closed loop: the position setpoint [m]
    excitation: SignalSpec | None = None  #: closed loop: added to the controller output [V]
    load_force: float = 0.0  #: constant external load [N]
    load: SignalSpec | None = None  #: open loop: external load per sample [N]
    regulated: tuple[float, float] | None = None  #: (p1, p2) held by regulators [Pa]

    @property
    def closed_loop(self) -> bool:
        """True for a closed-loop experiment."""
        return self.kind == "closed_loop"

    @property
    def start_position(self) -> float:
        """Where the regulated rig places the piston [m]: the end stop it leaves (outer,
        +stroke/2, when p2 > p1: entry phase; inner otherwise); 0 for other experiments."""
        if self.regulated is None:
            return 0.0
        return HALF_STROKE if self.regulated[1] > self.regulated[0] else -HALF_STROKE

    def command(self, dt: float) -> Command:
        """The experiment's command sampled every ``dt`` [s]."""
        if not self.closed_loop:
            n = samples(dt, self.duration)
            voltage = self.voltage.sample(dt, self.duration) if self.voltage else np.zeros(n)
            load = self.load.sample(dt, self.duration) if self.load else None
            return Command(voltage=voltage, load=load)
        assert self.setpoint is not None
        n = samples(dt, self.duration)
        excitation = (self.excitation.sample(dt, self.duration) if self.excitation
                      else np.zeros(n))
        return Command(setpoint=self.setpoint.sample(dt, self.duration), excitation=excitation)

    def to_yaml(self) -> dict[str, Any]:
        """The experiment as a campaign YAML mapping."""
        out: dict[str, Any] = {"name": self.name, "kind": self.kind, "locked": self.locked,
                               "role": self.role, "duration": self.duration}
        if self.regulated is not None:
            out["regulated"] = {"p1": self.regulated[0], "p2": self.regulated[1]}
        for key in ("voltage", "setpoint", "excitation", "load"):
            spec = getattr(self, key)
            if spec is not None:
                out[key] = spec.to_yaml()
        if self.load_force:
            out["load_force"] = self.load_force
        return out


@dataclass(frozen=True)
class Phase:
    """One stretch of a campaign's schedule: a settle phase or an experiment.

    ``experiment`` is None for settle phases (``label`` ``settle:center`` or ``settle:rest``).
    """

    label: str
    experiment: ExperimentSpec | None
    locked: bool  #: piston clamped during the phase
    command: Command
    load_force: float = 0.0  #: [N], when the command has no ``load``
    regulated: tuple[float, float] | None = None  #: (p1, p2) held by regulators [Pa]
    start_position: float = 0.0  #: [m] where the regulated rig places the piston
    place: bool = False  #: the rig sets the regulators and places the piston as it starts

    @property
    def samples(self) -> int:
        """Length of the phase [samples]."""
        return len(self.command)

    def rig(self) -> dict[str, Any]:
        """The test rig's model parameters over the phase: piston clamp, regulators and, when
        regulated, their pressures [Pa] and the piston's place [m] (applied with
        :meth:`~jetpipe_ros.model.Actuator.reconfigure` or the simulator's parameters)."""
        out: dict[str, Any] = {"mechanics.locked": self.locked,
                               "chamber.regulated": self.regulated is not None}
        if self.regulated is not None:
            out.update({"chamber.initial_pressure_1": self.regulated[0],
                        "chamber.initial_pressure_2": self.regulated[1],
                        "mechanics.initial_position": self.start_position})
        return out

    def rig_changes(self, current: Mapping[str, Any]) -> dict[str, Any]:
        """The rig parameters to set entering the phase from the rig ``current``: all of them
        when the rig places the piston, else those that differ."""
        rig = self.rig()
        return rig if self.place else {k: v for k, v in rig.items() if current.get(k) != v}


@dataclass(frozen=True)
class Campaign:
    """A list of experiments with the sample time and the settle phases between them."""

    experiments: tuple[ExperimentSpec, ...]
    sample_time: float = 0.001  #: [s]
    settle_center: float = 0.5  #: [s] closed loop to y = 0 before an experiment
    settle_rest: float = 0.5  #: [s] 0 V before an experiment
    source: str = "<memory>"  #: where the plan came from, for messages

    @property
    def duration(self) -> float:
        """Sum of the experiments' durations [s] (what the dataset holds)."""
        return float(sum(e.duration for e in self.experiments))

    def schedule(self) -> list[Phase]:
        """The phases in the order a runner executes them.

        Before each experiment: ``settle:center`` (piston free, closed loop to y = 0, skipped
        when the piston is locked before and during the experiment: it stays where it is
        clamped), then ``settle:rest`` (0 V, piston as the experiment wants it). A regulated
        experiment's first phase sets the regulators and places the piston (``place``); its
        ``settle:rest`` holds it there with the experiment's initial load.
        """
        dt = self.sample_time
        phases: list[Phase] = []
        locked = False
        for exp in self.experiments:
            if self.settle_center > 0.0 and not (locked and exp.locked):
                n = samples(dt, self.settle_center)
                phases.append(Phase("settle:center", None, False,
                                    Command(setpoint=np.zeros(n), excitation=np.zeros(n))))
                locked = False
            command = exp.command(dt)
            rig = {"regulated": exp.regulated, "start_position": exp.start_position}
            place = exp.regulated is not None
            if self.settle_rest > 0.0:
                load = exp.load_force if command.load is None else float(command.load[0])
                phases.append(Phase("settle:rest", None, exp.locked,
                                    Command(voltage=np.zeros(samples(dt, self.settle_rest))),
                                    load, place=place, **rig))
                place = False
            phases.append(Phase(exp.name, exp, exp.locked, command, exp.load_force,
                                place=place, **rig))
            locked = exp.locked
        return phases

    def total_duration(self) -> float:
        """Length of the whole schedule, settle phases included [s]."""
        return sum(p.samples for p in self.schedule()) * self.sample_time

    def select(self, names: Sequence[str]) -> Campaign:
        """The campaign restricted to the experiments ``names`` (in plan order)."""
        unknown = sorted(set(names) - {e.name for e in self.experiments})
        if unknown:
            raise CampaignError(f"{self.source}: no experiment named {', '.join(unknown)}; "
                                f"known: {', '.join(e.name for e in self.experiments)}")
        return Campaign(tuple(e for e in self.experiments if e.name in names), self.sample_time,
                        self.settle_center, self.settle_rest, self.source)

    def to_yaml(self) -> str:
        """The campaign as YAML that :func:`load_campaign` reads back."""
        return yaml.safe_dump({
            "sample_time": self.sample_time,
            "settle": {"center": self.settle_center, "rest": self.settle_rest},
            "experiments": [e.to_yaml() for e in self.experiments]}, sort_keys=False)


# -- loading -------------------------------------------------------------------------------


def _number(where: str, key: str, value: Any, low: float = -math.inf,
            high: float = math.inf, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or not low <= value <= high:
        unit = f" [{unit}]" if unit else ""
        raise CampaignError(f"{where}: field {key!r} must be a finite number{unit} in "
                            f"[{low:g}, {high:g}], got {value!r}")
    return float(value)


def _signal(where: str, key: str, raw: Any, dt: float, duration: float) -> SignalSpec:
    """Validate a signal mapping by sampling it once."""
    where = f"{where}, field {key!r}"
    if not isinstance(raw, Mapping) or "signal" not in raw:
        raise CampaignError(f"{where}: expected a mapping with 'signal: <one of "
                            f"{', '.join(GENERATORS)}>' and its arguments, got {raw!r}")
    args = dict(raw)
    name = args.pop("signal")
    if name not in GENERATORS:
        raise CampaignError(f"{where}: unknown signal {name!r}; known: {', '.join(GENERATORS)}")
    params = inspect.signature(GENERATORS[name]).parameters
    allowed = [p for p in params if p not in ("dt", "duration")]
    unknown = sorted(set(args) - set(allowed))
    missing = [p for p in allowed if params[p].default is inspect.Parameter.empty
               and p not in args]
    if unknown or missing:
        problem = (f"unknown argument(s) {', '.join(unknown)}" if unknown
                   else f"missing argument(s) {', '.join(missing)}")
        raise CampaignError(f"{where}: signal {name!r}: {problem}; it takes "
                            f"{', '.join(allowed)}")
    spec = SignalSpec(name, args)
    try:
        values = spec.sample(dt, duration)
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"{where}: signal {name!r}: {exc}") from None
    if not np.all(np.isfinite(values)):
        raise CampaignError(f"{where}: signal {name!r} gives non-finite values")
    return spec


def _experiment(where: str, raw: Any, dt: float) -> ExperimentSpec:
    if not isinstance(raw, Mapping):
        raise CampaignError(f"{where}: expected a mapping, got {raw!r}")
    raw = dict(raw)
    name = raw.get("name")
    if not isinstance(name, str) or not NAME.match(name):
        raise CampaignError(f"{where}: field 'name' must be a file-name-safe string "
                            f"(letters, digits, _ . -), got {name!r}")
    where = f"{where} ({name})"
    kind = raw.get("kind")
    if kind not in KINDS:
        raise CampaignError(f"{where}: field 'kind' must be one of {', '.join(KINDS)}, "
                            f"got {kind!r}")
    role = raw.get("role")
    if role not in ROLES:
        raise CampaignError(f"{where}: field 'role' must be one of {', '.join(ROLES)}, "
                            f"got {role!r}")
    locked = raw.get("locked", False)
    if not isinstance(locked, bool):
        raise CampaignError(f"{where}: field 'locked' must be true or false, got {locked!r}")
    duration = _number(where, "duration", raw.get("duration"), 2 * dt, 3600.0, "s")
    load = _number(where, "load_force", raw.get("load_force", 0.0), -1e4, 1e4, "N")
    regulated = None
    if kind == "open_loop":
        if "regulated" in raw:
            regulated = _regulated(where, raw["regulated"])
        # A regulated test holds the valve at 0 V unless told otherwise (it is irrelevant).
        wanted, optional = ((), ("voltage", "load")) if regulated else (("voltage",), ("load",))
    else:
        wanted, optional = ("setpoint",), ("excitation",)
    known = {"name", "kind", "role", "locked", "duration", "load_force", *wanted, *optional}
    if kind == "open_loop":
        known.add("regulated")
    unknown = sorted(set(raw) - known)
    if unknown:
        raise CampaignError(f"{where}: unknown field(s) {', '.join(unknown)} for a {kind} "
                            f"experiment; it takes {', '.join(sorted(known))}")
    if locked and kind == "closed_loop":
        raise CampaignError(f"{where}: a closed_loop experiment cannot have the piston locked")
    if "load" in raw and "load_force" in raw:
        raise CampaignError(f"{where}: give either 'load' (a signal [N]) or 'load_force' "
                            f"(constant [N]), not both")
    if regulated is not None:
        if locked:
            raise CampaignError(f"{where}: field 'regulated': the piston must be free "
                                f"(locked: false) in a regulated friction test")
        if "load" not in raw:
            raise CampaignError(f"{where}: field 'load' is missing (a regulated experiment "
                                f"needs the releasing load, e.g. {{signal: release, rate: "
                                f"1000.0}} [N])")
    raw_load = raw.get("load")
    if (regulated is not None and isinstance(raw_load, Mapping)
            and raw_load.get("signal") == "release" and "level" not in raw_load):
        raw = {**raw, "load": {**raw_load, "level": AREA * (regulated[0] - regulated[1])}}
    signals = {key: _signal(where, key, raw[key], dt, duration)
               for key in (*wanted, *optional) if key in raw}
    for key in wanted:
        if key not in signals:
            raise CampaignError(f"{where}: field {key!r} is missing (a {kind} experiment "
                                f"needs it)")
    return ExperimentSpec(name=name, kind=kind, duration=duration, locked=locked, role=role,
                          load_force=load, regulated=regulated, **signals)


def _regulated(where: str, raw: Any) -> tuple[float, float]:
    """Validate ``regulated: {p1: Pa, p2: Pa}``: two different absolute pressures."""
    where = f"{where}, field 'regulated'"
    if not isinstance(raw, Mapping) or set(raw) != {"p1", "p2"}:
        raise CampaignError(f"{where}: expected a mapping {{p1: <Pa>, p2: <Pa>}} (absolute "
                            f"chamber pressures held by the regulators), got {raw!r}")
    low, high = PRESSURE_RANGE
    p1, p2 = (_number(where, key, raw[key], low, high, "Pa") for key in ("p1", "p2"))
    if abs(p1 - p2) < 1e3:
        raise CampaignError(f"{where}: p1 and p2 must differ by at least 1000 Pa (the net "
                            f"force S (p1 - p2) sets the phase and slides the piston), got "
                            f"p1 = {p1:g}, p2 = {p2:g}")
    return p1, p2


def parse_campaign(doc: Any, source: str = "<memory>") -> Campaign:
    """Validate a campaign document (the parsed YAML); ``source`` names it in errors."""
    if not isinstance(doc, Mapping) or not isinstance(doc.get("experiments"), list):
        raise CampaignError(f"{source}: expected a mapping with an 'experiments:' list")
    unknown = sorted(set(doc) - {"sample_time", "settle", "experiments"})
    if unknown:
        raise CampaignError(f"{source}: unknown top-level field(s) {', '.join(unknown)}; "
                            f"expected sample_time, settle, experiments")
    dt = _number(source, "sample_time", doc.get("sample_time", 0.001), 1e-5, 1.0, "s")
    settle = doc.get("settle", {}) or {}
    if not isinstance(settle, Mapping) or set(settle) - {"center", "rest"}:
        raise CampaignError(f"{source}: field 'settle' must be a mapping with 'center' and/or "
                            f"'rest' [s], got {settle!r}")
    center = _number(source, "settle.center", settle.get("center", 0.5), 0.0, 60.0, "s")
    rest = _number(source, "settle.rest", settle.get("rest", 0.5), 0.0, 60.0, "s")
    experiments = tuple(_experiment(f"{source}: experiments[{i}]", raw, dt)
                        for i, raw in enumerate(doc["experiments"]))
    if not experiments:
        raise CampaignError(f"{source}: 'experiments' is empty")
    names = [e.name for e in experiments]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise CampaignError(f"{source}: experiment name(s) used twice: {', '.join(twice)}")
    return Campaign(experiments, dt, center, rest, source)


def load_campaign(path: str | Path) -> Campaign:
    """Read and validate a campaign YAML file (see the module docstring)."""
    path = Path(path)
    return parse_campaign(read_yaml(path, CampaignError), str(path))


def default_campaign() -> Campaign:
    """The package's ``config/campaign.yaml`` (the paper's campaign)."""
    return load_campaign(share_file("config/campaign.yaml"))
