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

Per session the state machine goes (``BenchSession.state`` names)::

    idle (waiting for the load change, if the load differs) -> cooling (torque off) or
    heating (walking, servos too cold) until every servo is inside the gate -> walking for
    walk_duration_s -> cooling (torque off) until inside the gate -> next session ... -> done

Time is whatever the caller passes (``t_s`` from message stamps or simulated time). Progress is
kept in a JSON state file, rewritten atomically (write + fsync + rename) each time a session
finishes, so a sequencer restarted after a crash resumes at the first unfinished session and
repeats none that finished.
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    'BenchPlan',
    'BenchSequencer',
    'PlanError',
    'SequencerCommand',
    'SessionSpec',
    'load_plan',
    'move_aside',
]


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
    return out


def load_plan(source: str | Path | Mapping[str, Any]) -> BenchPlan:
    """A BenchPlan from a YAML file or a mapping (see module doc)."""
    if isinstance(source, Mapping):
        data = source
    else:
        import yaml

        try:
            data = yaml.safe_load(Path(source).read_text()) or {}
        except (OSError, yaml.YAMLError) as err:
            raise PlanError(f'plan {str(source)!r}: cannot read: {err}') from err
    loads = _floats(data, 'loads_kg', None)
    freqs = _floats(data, 'frequencies_hz', None)
    betas = _floats(data, 'duty_factors', [0.5])
    steps = _floats(data, 'step_lengths_m', [0.1])
    height = float(data.get('step_height_m', 0.04))
    duration = float(data.get('walk_duration_s', 60.0))
    if any(x < 0 for x in loads) or any(f < 0 for f in freqs) or duration <= 0:
        raise PlanError('plan: loads_kg >= 0, frequencies_hz >= 0 (0: the basal session, the '
                        'leg standing at its load) and walk_duration_s > 0 expected; got '
                        f'{loads}, {freqs}, {duration}')
    if any(not 0 < b < 1 for b in betas):
        raise PlanError(f'plan: duty_factors must be in (0, 1), got {betas}')
    sessions = tuple(
        SessionSpec(f'load{load:.3f}kg_f{f:.2f}Hz_b{b:.2f}_s{s:.3f}m', load, f, b, s, height,
                    duration)
        for load, f, b, s in itertools.product(loads, freqs, betas, steps))
    return BenchPlan(sessions, float(data.get('temperature_gate_c', 26.0)),
                     float(data.get('temperature_tolerance_c', 1.0)))


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

    state : BenchSession state (idle, heating, walking, cooling, done, aborted).
    session : the current session (None when done).
    walk : the gait must run (heating and walking).
    torque : servos powered.
    load_request_kg : the operator must put this load on the stage and confirm (else None).
    record : the current session's measurement is being recorded (walking).
    """

    state: str
    session: SessionSpec | None
    walk: bool
    torque: bool
    load_request_kg: float | None = None
    record: bool = False
    finished_session: str | None = None


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
    """

    def __init__(self, plan: BenchPlan, *, state_file: str | Path | None = None,
                 initial_load_kg: float | None = None) -> None:
        self.plan = plan
        self.state_file = Path(state_file) if state_file is not None else None
        self.progress = self._load_progress()
        if initial_load_kg is not None:
            self.progress.current_load_kg = float(initial_load_kg)
        self.state = 'idle'
        self._walk_started_s: float | None = None
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

    def abort(self) -> SequencerCommand:
        self.state = 'aborted'
        return SequencerCommand('aborted', self.current, walk=False, torque=False)

    def update(self, t_s: float, temperatures_c: Sequence[float]) -> SequencerCommand:
        """Advance the state machine at time ``t_s`` [s] given every servo's temperature."""
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
                self.state = 'walking'
                self._walk_started_s = t_s
            elif hot:
                self.state = 'cooling_gate'
                return SequencerCommand('cooling', s, walk=False, torque=False)
            else:
                self.state = 'heating'   # too cold: walk (unrecorded) until warm
                return SequencerCommand('heating', s, walk=True, torque=True)
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
            nxt = self.update(t_s, temperatures_c)
            return SequencerCommand(nxt.state, nxt.session, nxt.walk, nxt.torque,
                                    nxt.load_request_kg, nxt.record, s.session_id)
        raise AssertionError(f'unreachable state {self.state!r}')
