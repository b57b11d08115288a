"""Bench sequencer core: a plan of sessions, a temperature gate, a crash-safe state file. No ROS.

A plan (YAML) is the product loads x frequencies (x duty factors x step lengths), ordered by
load first so the operator changes the weight as rarely as possible::

    loads_kg: [0.0, 0.095, 0.141]
    frequencies_hz: [0.0, 0.5, 1.0, 1.5]   # 0: the basal session (the leg stands at its load)
    duty_factors: [0.5]            # optional, default [0.5]
    step_lengths_m: [0.1]          # optional, default [0.1]
    step_height_m: 0.04
    walk_duration_s: 60.0
    temperature_gate_c: 26.0       # every servo within gate +- tolerance before walking
    temperature_tolerance_c: 1.0
    temperature_limit_c: 45.0      # optional: above it while walking, the plan is aborted

The plan is checked before anything moves: unknown keys (a typo would silently give a default),
values that are not finite or out of range, gaits beyond the actuator limits or out of the leg's
reach (:func:`hexapod_gait.config.build_gait`, the gait node's own rules) and two sessions with
one id are refused with the reason.

Per session the state machine goes (``BenchSession.state`` names)::

    idle (waiting for the load change, if the load differs) -> cooling (torque off) or
    heating (walking, servos too cold) until every servo is inside the gate -> starting (the
    gait ramps to the session gait, unrecorded, until the caller reports it steady) -> walking
    for walk_duration_s -> cooling (torque off) until inside the gate -> next session ... -> done

``starting`` lasts until ``update(..., gait_ready=True)`` (None: at once), at most
``stand_timeout_s``, and until every recorded topic has been received (``unseen_topics``
empty), at most the longer of ``stand_timeout_s`` and ``stream_timeout_s``; then the plan
is aborted (the gait node does not walk the session gait, or a recorded topic has no working
publisher: its name and owner are given, and the session is not recorded without it), so a
session's recording holds only the steady gait, with every topic.

Stand before torque off: after a walk (or an abort), the torque stays on until the leg reports
standing (``standing=True``). When it cannot stand, the torque is **kept on**, never cut
under a loaded leg that is not standing (a dropping leg is worse than a held one): the gait node
did not report the stand within ``stand_timeout_s`` (``standing=False``), or its parameter
service is gone (``stand_unavailable``: no wait for a stand it cannot deliver). The plan is
then aborted, the command says ``hold`` and :attr:`BenchSequencer.hold_reason` tells the
operator to support the stage before turning the torque off. Only a stand that nobody reports
(``standing=None``: no gait node) still ends with the torque off after ``stand_timeout_s``.

Time is whatever the caller passes (``t_s`` from message stamps or simulated time). Progress is
kept in a JSON state file, rewritten atomically (write + fsync + rename) each time a session
finishes, so a sequencer restarted after a crash resumes at the first unfinished session and
repeats none that finished.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    'BenchPlan',
    'BenchSequencer',
    'HEAT_FREQUENCY_HZ',
    'OVERHEATING_FLAG',
    'PLAN_KEYS',
    'PlanError',
    'SequencerCommand',
    'STREAM_OWNERS',
    'SessionSpec',
    'load_plan',
    'move_aside',
    'stream_owner',
]


#: step frequency [Hz] that heats the servos into the gate before a basal (0 Hz) session
HEAT_FREQUENCY_HZ = 1.0

#: ``ServoStatus.error`` bit of an overheating servo (Dynamixel protocol 1.0 and 2.0 alike)
OVERHEATING_FLAG = 1 << 2

#: Keys a plan may have (any other is refused: a typo would silently give the default).
PLAN_KEYS = ('loads_kg', 'frequencies_hz', 'duty_factors', 'step_lengths_m', 'step_height_m',
             'walk_duration_s', 'temperature_gate_c', 'temperature_tolerance_c',
             'temperature_limit_c')


#: Who publishes each watched stream (named when it goes silent or never comes).
STREAM_OWNERS = {
    'servo_status': 'the servo driver (dynamixel_driver)',
    'joint_states': 'the servo driver (dynamixel_driver)',
    'battery_state': 'the power monitor (power_monitor)',
    'bench/ground_force': 'the force sensor (force_sensor)',
    'bench/leg_tip': 'the motion capture (its ROS bridge)',
    'gait/phase': 'the gait node (gait_scheduler)',
    'joint_commands': 'the gait node (gait_scheduler)',
}


def stream_owner(topic: str) -> str:
    """Who publishes ``topic`` (:data:`STREAM_OWNERS`; a namespace prefix is ignored)."""
    name = topic.strip('/')
    for key, owner in STREAM_OWNERS.items():
        if name == key or name.endswith('/' + key):
            return owner
    return f'the publisher of {name}'


class PlanError(ValueError):
    """A bench plan is malformed."""


@dataclass(frozen=True)
class SessionSpec:
    """One bench session: a load on the stage and a gait."""

    session_id: str
    load_kg: float
    frequency_hz: float
    duty_factor: float
    step_length_m: float
    step_height_m: float
    duration_s: float


@dataclass(frozen=True)
class BenchPlan:
    sessions: tuple[SessionSpec, ...]
    temperature_gate_c: float = 26.0
    temperature_tolerance_c: float = 1.0
    temperature_limit_c: float = 45.0


def _floats(data: Mapping[str, Any], key: str, default: Sequence[float] | None) -> list[float]:
    value = data.get(key, default)
    if value is None:
        raise PlanError(f'plan: {key!r} is required (a list of numbers)')
    if isinstance(value, (int, float)):
        value = [value]
    try:
        out = [float(v) for v in value]
    except (TypeError, ValueError) as err:
        raise PlanError(f'plan: {key!r}: expected a list of numbers, got {value!r}') from err
    if not out:
        raise PlanError(f'plan: {key!r} is empty')
    bad = [v for v in out if not math.isfinite(v)]
    if bad:
        raise PlanError(f'plan: {key!r}: expected finite numbers, got {bad[0]!r} in {out}')
    return out


def _float(data: Mapping[str, Any], key: str, default: float) -> float:
    value = data.get(key, default)
    try:
        out = float(value)
    except (TypeError, ValueError) as err:
        raise PlanError(f'plan: {key!r}: expected a number, got {value!r}') from err
    if not math.isfinite(out):
        raise PlanError(f'plan: {key!r}: expected a finite number, got {out!r}')
    return out


def _check_gaits(sessions: Sequence[SessionSpec], limits: Any, leg: Any = None) -> None:
    """Refuse a session gait the gait node would refuse (actuator limits, leg reach) on
    ``leg`` (a :class:`hexapod_gait.leg_file.LegFile`, the gait node's ``-p leg_file``; None:
    AntBot's leg); ``limits`` (default AntBot's servo limits) carry the leg they were measured
    on (``measured_on``), against whose bench path each step is scaled."""
    from hexapod_gait.config import build_gait
    from hexapod_gait.errors import HexapodGaitError
    from hexapod_gait.feasibility import ActuatorLimits

    limits = limits if limits is not None else ActuatorLimits()

    checked = set()
    for s in sessions:
        f = s.frequency_hz if s.frequency_hz > 0 else HEAT_FREQUENCY_HZ   # basal: heating walk
        key = (f, s.duty_factor, s.step_length_m, s.step_height_m)
        if key in checked:
            continue
        checked.add(key)
        own = {} if leg is None else {'kinematics': leg.kinematics(),
                                      'neutral_tip_m': leg.neutral_tip_m}
        try:
            build_gait('tripod', duty_factor=s.duty_factor, period_s=1.0 / f,
                       step_length_m=s.step_length_m, step_height_m=s.step_height_m,
                       limits=limits, **own)
        except HexapodGaitError as err:
            raise PlanError(f'plan: session {s.session_id} ({f:g} Hz, duty factor '
                            f'{s.duty_factor:g}, step {s.step_length_m:g} m): the gait node '
                            f'would refuse it: {err}; change or remove it') from err


def load_plan(source: str | Path | Mapping[str, Any], *, limits: Any = None,
              leg: Any = None) -> BenchPlan:
    """A BenchPlan from a YAML file or a mapping (see module doc).

    ``limits`` : :class:`hexapod_gait.feasibility.ActuatorLimits` the session gaits must meet
    (default: the gait node's defaults).
    ``leg`` : :class:`hexapod_gait.leg_file.LegFile` of the bench leg (the gait node's
    ``-p leg_file``), whose reach and joint paths the gaits are checked on; None: AntBot's
    (an outside review: a plan the gait node walks on a longer leg was refused as one "the gait
    node would refuse", and one it refuses on a shorter leg was accepted).
    """
    if isinstance(source, Mapping):
        data = source
    else:
        import yaml

        try:
            data = yaml.safe_load(Path(source).read_text()) or {}
        except (OSError, yaml.YAMLError) as err:
            raise PlanError(f'plan {str(source)!r}: cannot read: {err}') from err
    if not isinstance(data, Mapping):
        raise PlanError(f'plan: expected a mapping of keys {list(PLAN_KEYS)}, got {data!r}')
    unknown = sorted(str(k) for k in data if k not in PLAN_KEYS)
    if unknown:
        raise PlanError(f'plan: unknown keys {unknown} (a typo would silently give the '
                        f'default); the keys are {list(PLAN_KEYS)}')
    loads = _floats(data, 'loads_kg', None)
    freqs = _floats(data, 'frequencies_hz', None)
    betas = _floats(data, 'duty_factors', [0.5])
    steps = _floats(data, 'step_lengths_m', [0.1])
    height = _float(data, 'step_height_m', 0.04)
    duration = _float(data, 'walk_duration_s', 60.0)
    if any(x < 0 for x in loads) or any(f < 0 for f in freqs) or duration <= 0:
        raise PlanError('plan: loads_kg >= 0, frequencies_hz >= 0 (0: the basal session, the '
                        'leg standing at its load) and walk_duration_s > 0 expected; got '
                        f'{loads}, {freqs}, {duration}')
    if any(not 0 < b < 1 for b in betas):
        raise PlanError(f'plan: duty_factors must be in (0, 1), got {betas}')
    if any(x <= 0 for x in steps) or height < 0:
        raise PlanError(f'plan: step_lengths_m > 0 and step_height_m >= 0 expected; got '
                        f'{steps}, {height}')
    gate = _float(data, 'temperature_gate_c', 26.0)
    tol = _float(data, 'temperature_tolerance_c', 1.0)
    limit = _float(data, 'temperature_limit_c', 45.0)
    if tol <= 0:
        raise PlanError(f'plan: temperature_tolerance_c must be > 0 (else the gate is never '
                        f'met), got {tol}')
    if limit <= gate + tol:
        raise PlanError(f'plan: temperature_limit_c ({limit}) must be above the gate '
                        f'temperature_gate_c + temperature_tolerance_c ({gate + tol})')
    sessions = tuple(
        SessionSpec(f'load{load:.3f}kg_f{f:.2f}Hz_b{b:.2f}_s{s:.3f}m', load, f, b, s, height,
                    duration)
        for load, f, b, s in itertools.product(loads, freqs, betas, steps))
    seen: dict[str, SessionSpec] = {}
    for s in sessions:
        if s.session_id in seen:
            o = seen[s.session_id]
            raise PlanError(
                f'plan: two sessions have the id {s.session_id!r} (load {o.load_kg!r} and '
                f'{s.load_kg!r} kg, {o.frequency_hz!r} and {s.frequency_hz!r} Hz, duty factor '
                f'{o.duty_factor!r} and {s.duty_factor!r}, step {o.step_length_m!r} and '
                f'{s.step_length_m!r} m): the second would be skipped; remove the repeat or '
                'make the values differ in the 3rd (kg, m) or 2nd (Hz, duty) decimal')
        seen[s.session_id] = s
    _check_gaits(sessions, limits, leg)
    return BenchPlan(sessions, gate, tol, limit)


def move_aside(path: Path) -> Path | None:
    """Rename an existing ``path`` to ``<name>.interrupted-N`` (first free N); returns it."""
    if not path.exists():
        return None
    k = 1
    while path.with_name(f'{path.name}.interrupted-{k}').exists():
        k += 1
    target = path.with_name(f'{path.name}.interrupted-{k}')
    path.rename(target)
    return target


@dataclass(frozen=True)
class SequencerCommand:
    """What the bench should do now.

    state : BenchSession state (idle, heating, starting, walking, cooling, done, aborted).
    session : the current session (None when done).
    walk : the gait must run (heating and walking).
    torque : servos powered.
    load_request_kg : the operator must put this load on the stage and confirm (else None).
    record : the current session's measurement is being recorded (walking).
    finished_session : id of the session completed on this update (else None).
    standing : the leg is being stood before the torque goes off (walk false, torque true).
    hold : the leg could not be stood: the torque is kept on (torque true) and the plan ends
        (aborted); see :attr:`BenchSequencer.hold_reason`.
    """

    state: str
    session: SessionSpec | None
    walk: bool
    torque: bool
    load_request_kg: float | None = None
    record: bool = False
    finished_session: str | None = None
    standing: bool = False
    hold: bool = False


@dataclass
class _Progress:
    completed: list[str] = field(default_factory=list)
    current_load_kg: float | None = None


class BenchSequencer:
    """The session state machine (see module doc).

    Parameters
    ----------
    plan : BenchPlan
    state_file : path, optional
        JSON progress file; read at start (resume) and rewritten after each session.
    initial_load_kg : float, optional
        Load on the stage at start (None: unknown, so the first session asks for its load).
    torque_controlled : bool
        The caller turns the servos' torque on and off as commanded (False: no torque service;
        the messages then never claim the torque went off).
    """

    def __init__(self, plan: BenchPlan, *, state_file: str | Path | None = None,
                 initial_load_kg: float | None = None, stand_timeout_s: float = 10.0,
                 stream_timeout_s: float = 5.0, torque_controlled: bool = True) -> None:
        if not (math.isfinite(stand_timeout_s) and stand_timeout_s > 0
                and math.isfinite(stream_timeout_s) and stream_timeout_s > 0):
            raise PlanError(f'stand_timeout_s = {stand_timeout_s!r}, stream_timeout_s = '
                            f'{stream_timeout_s!r}: expected finite and > 0 s')
        self.plan = plan
        self.state_file = Path(state_file) if state_file is not None else None
        self.progress = self._load_progress()
        if initial_load_kg is not None:
            self.progress.current_load_kg = float(initial_load_kg)
        self.state = 'idle'
        self.stand_timeout_s = float(stand_timeout_s)
        self.stream_timeout_s = float(stream_timeout_s)
        #: why the plan was aborted ('' while it is not)
        self.abort_reason = ''
        #: set when the stand before a torque off timed out (for the log), else ''
        self.stand_warning = ''
        #: why the leg could not be stood and the torque is kept on (see module doc), else ''
        self.hold_reason = ''
        self.torque_controlled = bool(torque_controlled)
        self._walk_started_s: float | None = None
        self._starting_since_s: float | None = None
        self._moved = False                 # walked since the torque was last off
        self._stand_since_s: float | None = None
        self.skipped = [s.session_id for s in plan.sessions
                        if s.session_id in self.progress.completed]

    # --- progress file ---------------------------------------------------------------------
    def _load_progress(self) -> _Progress:
        if self.state_file is None or not self.state_file.exists():
            return _Progress()
        try:
            data = json.loads(self.state_file.read_text())
            return _Progress(list(data['completed']), data.get('current_load_kg'))
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise PlanError(f'state file {str(self.state_file)!r}: unreadable ({err}); '
                            'move it away to start the plan afresh') from err

    def _save_progress(self) -> None:
        if self.state_file is None:
            return
        tmp = self.state_file.with_suffix(self.state_file.suffix + '.tmp')
        with open(tmp, 'w') as f:
            json.dump(asdict(self.progress), f, indent=1)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.state_file)

    # --- queries ---------------------------------------------------------------------------
    @property
    def completed(self) -> list[str]:
        return list(self.progress.completed)

    @property
    def current(self) -> SessionSpec | None:
        """First session not completed (None when the plan is done)."""
        for s in self.plan.sessions:
            if s.session_id not in self.progress.completed:
                return s
        return None

    def in_gate(self, temperatures_c: Sequence[float]) -> bool:
        """Every servo within gate +- tolerance (no temperatures, or a NaN: not in the gate)."""
        g, tol = self.plan.temperature_gate_c, self.plan.temperature_tolerance_c
        return bool(temperatures_c) and all(abs(t - g) <= tol for t in temperatures_c)

    # --- transitions -----------------------------------------------------------------------
    def confirm_load(self, load_kg: float | None = None) -> None:
        """The operator (or the simulator) has put the requested load on the stage."""
        s = self.current
        self.progress.current_load_kg = (float(load_kg) if load_kg is not None
                                         else (s.load_kg if s is not None else None))

    def abort(self, reason: str = 'aborted by the operator') -> SequencerCommand:
        """Stop the plan: the next updates stand the leg (if it walked), then torque off.

        The current session is not counted; the state is ``aborted`` from now on.
        """
        if self.state != 'aborted':
            self.state = 'aborted'
            self.abort_reason = reason
            self._walk_started_s = None
        return SequencerCommand('aborted', self.current, walk=False, torque=self._moved,
                                standing=self._moved)

    def fault(self, temperatures_c: Sequence[float], error_flags: Sequence[int] = (),
              stream_ages_s: Mapping[str, float] | None = None) -> str | None:
        """Why the leg must stop walking now (None if nothing is wrong); see module doc."""
        limit = self.plan.temperature_limit_c
        flags = [(i, int(f)) for i, f in enumerate(error_flags) if int(f)]
        if flags:
            i, f = flags[0]
            what = 'overheating' if f & OVERHEATING_FLAG else 'a hardware error'
            return (f'servo {i} reports {what} (error flags 0x{f:02x}; all: '
                    f'{[hex(int(x)) for x in error_flags]}); let it cool and check it')
        hot = [t for t in temperatures_c if t > limit]
        if hot:
            return (f'servo temperature {max(hot):g} degC > temperature_limit_c {limit:g} '
                    f'degC while walking; let the servos cool and check the leg')
        for topic, age in (stream_ages_s or {}).items():
            if not age <= self.stream_timeout_s:
                return (f'no {topic} for {age:.2f} s (stream_timeout_s = '
                        f'{self.stream_timeout_s:g} s) while '
                        f'walking: the session would lack data or run unwatched; check '
                        f'{stream_owner(topic)}, then restart the plan (it resumes at this '
                        'session)')
        return None

    def update(self, t_s: float, temperatures_c: Sequence[float], *,
               error_flags: Sequence[int] = (),
               stream_ages_s: Mapping[str, float] | None = None,
               standing: bool | None = None,
               gait_ready: bool | None = None,
               unseen_topics: Sequence[str] = (),
               stand_unavailable: str = '') -> SequencerCommand:
        """Advance the state machine at time ``t_s`` [s] given every servo's temperature.

        error_flags : every servo's ``ServoStatus.error`` byte (any non-zero one while
            walking aborts the plan, see module doc).
        stream_ages_s : seconds since the last message of each watched stream
            (``servo_status``, ``battery_state``, ...); one older than ``stream_timeout_s``
            while walking aborts the plan, and so does ``servo_status`` (finite age: seen
            before) while cooling.
        standing : the leg has reached the stand (the gait node settled at step 0); None:
            unknown, the stand before a torque off then lasts ``stand_timeout_s``.
        gait_ready : the gait node walks the current session's gait, settled (None: unknown,
            the recorded walk starts at once).
        unseen_topics : recorded topics not received yet; ``starting`` waits for them, at
            most the longer of ``stand_timeout_s`` and ``stream_timeout_s``, then aborts
            naming them and their owners.
        stand_unavailable : why the leg cannot be stood now (the gait node's parameter
            service is gone), else ''; a leg that must stand then keeps its torque at once
            (``hold``), without waiting ``stand_timeout_s``.
        """
        if self.state in ('heating', 'starting', 'walking'):
            reason = self.fault(temperatures_c, error_flags, stream_ages_s)
            if reason is not None:
                self.abort(reason)
        elif self.state in ('cooling_gate', 'cooling_after'):
            # the gate waits for temperatures: a driver gone silent (seen before) would leave
            # the plan cooling for ever without a word (outside integration review D6)
            age = (stream_ages_s or {}).get('servo_status', math.inf)
            if math.isfinite(age) and age > self.stream_timeout_s:
                self.abort(f'no servo_status for {age:.2f} s (stream_timeout_s = '
                           f'{self.stream_timeout_s:g} s) while cooling: the temperature gate '
                           f'cannot be checked; check {stream_owner("servo_status")}, then '
                           'restart the plan (it resumes at this session)')
        cmd = self._update(t_s, temperatures_c, gait_ready, tuple(unseen_topics))
        return self._stand_first(t_s, cmd, standing, stand_unavailable)

    def _stand_first(self, t_s: float, cmd: SequencerCommand, standing: bool | None,
                     stand_unavailable: str = '') -> SequencerCommand:
        """Never cut the torque of a leg that walked before it stands (module doc)."""
        if self.hold_reason:
            return self._held(cmd)
        if cmd.walk:
            self._moved, self._stand_since_s = True, None
            return cmd
        if cmd.torque or not self._moved:
            self._stand_since_s = None
            return cmd
        first = self._stand_since_s is None
        if first:                                # first tick of the stand: torque stays on
            self._stand_since_s = t_s
            self.stand_warning = ''
        if stand_unavailable and not standing:
            return self._hold(cmd, stand_unavailable)
        if not first and (standing or t_s - self._stand_since_s >= self.stand_timeout_s):
            if standing is False:
                return self._hold(cmd, f'the gait node did not report the leg standing within '
                                       f'stand_timeout_s = {self.stand_timeout_s:g} s')
            if standing is None:
                self.stand_warning = (
                    f'nothing reports whether the leg stands (no gait node): stand_timeout_s '
                    f'= {self.stand_timeout_s:g} s over, '
                    + ('torque off now (a leg that is not standing drops)'
                       if self.torque_controlled else
                       'the sequencer does not control the torque (no torque service): the '
                       'servos keep theirs'))
            self._moved, self._stand_since_s = False, None
            return cmd
        return SequencerCommand(cmd.state, cmd.session, walk=False, torque=True,
                                load_request_kg=cmd.load_request_kg,
                                finished_session=cmd.finished_session, standing=True)

    def _hold(self, cmd: SequencerCommand, why: str) -> SequencerCommand:
        """The leg cannot be stood: keep its torque, end the plan (module doc)."""
        torque = ('torque kept ON so that the loaded leg does not drop; support the stage '
                  '(or the leg), then turn the torque off' if self.torque_controlled else
                  'the sequencer does not control the torque (no torque service); support '
                  'the stage (or the leg) before the torque goes off')
        self.hold_reason = f'the leg was NOT stood ({why}): {torque}'
        if self.state != 'aborted':
            self.abort(self.hold_reason)
        self._stand_since_s = None
        return self._held(cmd)

    def _held(self, cmd: SequencerCommand) -> SequencerCommand:
        return SequencerCommand('aborted', cmd.session, walk=False, torque=True,
                                finished_session=cmd.finished_session, hold=True)

    def _update(self, t_s: float, temperatures_c: Sequence[float],
                gait_ready: bool | None = None,
                unseen: tuple[str, ...] = ()) -> SequencerCommand:
        if self.state == 'aborted':
            return SequencerCommand('aborted', self.current, walk=False, torque=False)
        s = self.current
        if s is None:
            self.state = 'done'
            return SequencerCommand('done', None, walk=False, torque=False)
        load = self.progress.current_load_kg
        if self.state in ('idle', 'done') and (load is None or abs(load - s.load_kg) > 1e-9):
            self.state = 'idle'
            return SequencerCommand('idle', s, walk=False, torque=False, load_request_kg=s.load_kg)
        g, tol = self.plan.temperature_gate_c, self.plan.temperature_tolerance_c
        # NaN (a servo that did not answer) or no reading at all counts as too hot: torque off.
        hot = not temperatures_c or any(not t <= g + tol for t in temperatures_c)
        if self.state in ('idle', 'done', 'heating', 'cooling_gate'):
            if self.in_gate(temperatures_c):
                self.state, self._starting_since_s = 'starting', t_s
            elif hot:
                self.state = 'cooling_gate'
                return SequencerCommand('cooling', s, walk=False, torque=False)
            else:
                self.state = 'heating'   # too cold: walk (unrecorded) until warm
                return SequencerCommand('heating', s, walk=True, torque=True)
        if self.state == 'starting':
            assert self._starting_since_s is not None
            if gait_ready is False or unseen:
                # a recorded topic may take a discovery round or a slow stream's period
                unseen_wait_s = max(self.stand_timeout_s, self.stream_timeout_s)
                waited_s = t_s - self._starting_since_s
                if waited_s < (self.stand_timeout_s if gait_ready is False else unseen_wait_s):
                    return SequencerCommand('starting', s, walk=True, torque=True)
                if gait_ready is False:
                    self.abort(f'the gait node did not settle at the session gait of '
                               f'{s.session_id} within stand_timeout_s = '
                               f'{self.stand_timeout_s:g} s; check it (is it running, does it '
                               'accept the gait?)')
                else:
                    owners = '; '.join(f'{t}: {stream_owner(t)}' for t in unseen)
                    it = 'it' if len(unseen) == 1 else 'them'
                    self.abort(f'no message on {list(unseen)} by the end of the starting '
                               f'phase ({unseen_wait_s:g} s: the longer of stand_timeout_s and '
                               'stream_timeout_s): the '
                               f'session would be recorded without {it}; start the publisher '
                               f'({owners}) and check the topic name and QoS, or leave {it} '
                               'out of record_topics, then restart the plan')
                return SequencerCommand('aborted', s, walk=False, torque=False)
            self.state, self._walk_started_s = 'walking', t_s
        if self.state == 'walking':
            assert self._walk_started_s is not None
            if t_s - self._walk_started_s < s.duration_s:
                return SequencerCommand('walking', s, walk=True, torque=True, record=True)
            self.state = 'cooling_after'
        if self.state == 'cooling_after':
            if hot:
                return SequencerCommand('cooling', s, walk=False, torque=False)
            self.progress.completed.append(s.session_id)
            self._save_progress()
            self.state = 'idle'
            # gait_ready was the finished session's: the next one's gait is not settled yet
            # (its recording began on the ramp up when no cooling came between: a second
            # review)
            nxt = self._update(t_s, temperatures_c, None if gait_ready is None else False,
                               unseen)
            return SequencerCommand(nxt.state, nxt.session, nxt.walk, nxt.torque,
                                    nxt.load_request_kg, nxt.record, s.session_id)
        raise AssertionError(f'unreachable state {self.state!r}')
