"""The bench sequencer driving the MiMiC-Ant bench simulator in accelerated time. No ROS.

:class:`SimulatedBench` wraps the bench simulator's core (:mod:`.bench_sim`): it executes a
:class:`~.sequencer.SequencerCommand` for a stretch of simulated time (walk the session's gait,
stand powered, or cool with the supply off), so the servo thermal model heats while walking and
cools with torque off, and it reports the servos' temperatures as they would arrive on
``/servo_status`` (integer degC). :class:`SimulatedBenchRun` closes the loop: the sequencer core
gates on those temperatures, and each session's walk is written to its own bag
``<output_dir>/<session_id>`` with the topics of the real drivers (``/battery_state``,
``/bench/ground_force``, ``/bench/leg_tip``, ``/bench/session``, ``/joint_states``, ...), which
``hexapod-analyze energy --bench`` reads.

Crash safety is the sequencer core's state file: a run stopped at any point and started again
with the same state file resumes at the first unfinished session. A bag left by an unfinished
attempt is moved aside to ``<session_id>.interrupted-N``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import astuple, dataclass, field
from pathlib import Path

import numpy as np

from hexapod_gait.leg_file import LegFile

from .bench_sim import BenchConfig, BenchSimulator
from .bench_sim import BenchPlan as SimBenchPlan
from .bench_sim import BenchSession as SimBenchSession
from .effects import EffectSet
from .sequencer import BenchPlan, BenchSequencer, SequencerCommand, SessionSpec, move_aside
from .sim_core import SessionRecord, SimTrace, TraceBuilder

__all__ = ['RunEvent', 'SimulatedBench', 'SimulatedBenchRun']


def _sim_session(s: SessionSpec) -> SimBenchSession:
    return SimBenchSession(s.load_kg, s.frequency_hz, s.duty_factor, s.step_length_m,
                           s.step_height_m)


class SimulatedBench:
    """The bench simulator stepped by sequencer commands.

    Parameters
    ----------
    config : BenchConfig, optional
        Bench hardware; ``initial_temperature_c`` above the gate makes a hot start that the
        temperature gate must hold, ``ambient_temperature_c`` is where the servos cool to.
    effects : EffectSet, optional
        Named effects of the simulator (default: its defaults).
    seed : int
        Noise seed.
    stand_s : float
        Powered standing before each measured walk, while the stop is set [s].
    leg : LegFile, optional
        The bench leg (``bench_sequencer -p leg_file``, the gait node's leg file): its links,
        masses, neutral tip and inverse kinematics (:class:`~.bench_sim.BenchSimulator`);
        None: AntBot's leg.
    """

    def __init__(self, config: BenchConfig | None = None, *, effects: EffectSet | None = None,
                 seed: int = 0, stand_s: float = 1.0, leg: LegFile | None = None) -> None:
        self.sim = BenchSimulator(config, effects=effects, seed=seed, leg=leg)
        self.stand_s = float(stand_s)
        self.load_kg = 0.0
        self._walk_origin_s: float | None = None
        self._walk_key: tuple[str, bool] | None = None

    @property
    def t_s(self) -> float:
        """Simulated time [s]."""
        return self.sim.t_s

    @property
    def temperatures_c(self) -> list[float]:
        """Every servo's temperature as ``/servo_status`` reports it (integer degC)."""
        return [float(t) for t in np.rint(self.sim.servos.temperature_c)]

    def advance(self, cmd: SequencerCommand, duration_s: float) -> TraceBuilder | None:
        """Run the bench for ``duration_s`` [s] of simulated time as ``cmd`` says.

        Walking (``cmd.walk``) samples at the bench rate with the session's gait,
        phase-continuous over consecutive calls; powered standing likewise; torque off cools
        at the bench's cooling rate with longer servo sub-steps. Returns the samples (None for
        a command without a session, e.g. ``done``).
        """
        s = cmd.session
        if s is None or duration_s <= 0:
            return None
        cfg = self.sim.config
        session = _sim_session(SessionSpec(s.session_id, self.load_kg, s.frequency_hz,
                                           s.duty_factor, s.step_length_m, s.step_height_m,
                                           s.duration_s))
        if cmd.walk:
            key = (s.session_id, cmd.record)
            if key != self._walk_key:
                if cmd.record:
                    self._set_stop(session)
                self._walk_key, self._walk_origin_s = key, self.sim.t_s
            n = max(1, int(round(duration_s * cfg.rate_hz)))
            return self.sim._segment(n, 1.0 / cfg.rate_hz, session, walking=True, powered=True,
                                     origin_s=self._walk_origin_s)
        self._walk_key = None
        if cmd.torque:
            n = max(1, int(round(duration_s * cfg.rate_hz)))
            return self.sim._segment(n, 1.0 / cfg.rate_hz, session, walking=False,
                                     powered=True)
        dt = 1.0 / cfg.cooling_rate_hz
        n = max(1, int(round(duration_s * cfg.cooling_rate_hz)))
        servos = self.sim.servos
        substep, servos.max_substep_s = servos.max_substep_s, dt
        try:
            return self.sim._segment(n, dt, session, walking=False, powered=False)
        finally:
            servos.max_substep_s = substep

    def _set_stop(self, session: SimBenchSession) -> None:
        """Before a measured walk the operator powers the leg standing (``stand_s``, not
        recorded) and sets the stop just under its loaded standing height."""
        cfg = self.sim.config
        n = max(1, int(round(self.stand_s * cfg.rate_hz)))
        self.sim._segment(n, 1.0 / cfg.rate_hz, session, walking=False, powered=True)
        standing = self.sim.kinematics.forward(self.sim.servos.output_position_rad())[0]
        self.sim.stop_z = float(-standing[2]) - cfg.stop_drop_m

    def trace(self, parts: list[TraceBuilder], records: list[SessionRecord],
              session: SessionSpec) -> SimTrace:
        """Samples of ``parts`` as one trace, with the ``/bench/session`` ``records``."""
        plan = SimBenchPlan(loads_kg=(session.load_kg,), frequencies_hz=(session.frequency_hz,),
                            walk_s=session.duration_s, duty_factor=session.duty_factor,
                            step_length_m=session.step_length_m,
                            step_height_m=session.step_height_m)
        return self.sim._concat(parts, records, plan)


@dataclass(frozen=True)
class RunEvent:
    """Something that happened in a simulated run (for logs and tests).

    kind : 'walk' (measured walk started), 'bag' (a session's bag written), 'interrupted'
        (an aborted walk's partial bag moved aside; detail: where), 'finished' (session
        completed and saved in the state file), 'load' (load changed), 'state' (sequencer
        state changed).
    temperatures_c : servo temperatures when it happened [degC].
    """

    kind: str
    session_id: str
    t_s: float
    temperatures_c: tuple[float, ...] = ()
    detail: str = ''


@dataclass
class SimulatedBenchRun:
    """A bench plan run by the sequencer core on :class:`SimulatedBench` in accelerated time.

    Parameters
    ----------
    plan : BenchPlan
        The sequencer's plan (:func:`~.sequencer.load_plan`).
    bench : SimulatedBench
    state_file : path or None
        Progress file (resume after a crash).
    output_dir : path or None
        Folder of the per-session bags (None: no bags).
    step_s : float
        Simulated time per update of the state machine while powered [s]; walks last a whole
        number of steps (at least ``walk_duration_s``).
    cool_step_s : float
        Simulated time per update while the torque is off [s].
    storage : str
        Bag storage plugin ('mcap' or 'sqlite3').
    """

    plan: BenchPlan
    bench: SimulatedBench
    state_file: str | Path | None = None
    output_dir: str | Path | None = None
    step_s: float = 0.5
    cool_step_s: float = 5.0
    storage: str = 'mcap'
    events: list[RunEvent] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not (self.step_s > 0 and self.cool_step_s > 0):
            raise ValueError(f'step_s = {self.step_s!r}, cool_step_s = {self.cool_step_s!r}: '
                             'expected > 0 s')
        self.seq = BenchSequencer(self.plan, state_file=self.state_file)
        if self.seq.progress.current_load_kg is not None:
            # Resumed: the stage still carries the load the state file says it does (a fresh
            # simulator after a restart must not silently walk the next sessions unloaded).
            self.bench.load_kg = self.seq.progress.current_load_kg
        self.last: SequencerCommand | None = None
        self._parts: list[TraceBuilder] = []
        self._records: list[SessionRecord] = []
        self._recording: SessionSpec | None = None

    @property
    def done(self) -> bool:
        # done once the leg has stood and the torque is off (the last stand lasts one step)
        return self.last is not None and self.last.state == 'done' and not self.last.torque

    def _event(self, kind: str, sid: str, detail: str = '') -> None:
        self.events.append(RunEvent(kind, sid, self.bench.t_s,
                                    tuple(self.bench.temperatures_c), detail))

    def step(self) -> SequencerCommand:
        """One update of the state machine, then the bench runs the command for one step."""
        bench = self.bench
        # The simulated leg stands at once (its powered standing needs no transition).
        cmd = self.seq.update(bench.t_s, bench.temperatures_c, standing=True)
        if cmd.finished_session:
            self._event('finished', cmd.finished_session)
        if cmd.load_request_kg is not None:        # automatic load change in simulation
            bench.load_kg = cmd.load_request_kg
            self.seq.confirm_load(cmd.load_request_kg)
            self._event('load', cmd.session.session_id if cmd.session else '',
                        f'{cmd.load_request_kg:g} kg')
        prev = self.last
        if prev is None or (prev.state, prev.session) != (cmd.state, cmd.session):
            self._event('state', cmd.session.session_id if cmd.session else '', cmd.state)
        self._record_transition(cmd)
        self.last = cmd
        part = bench.advance(cmd, self.step_s if cmd.torque else self.cool_step_s)
        if part is not None and self._recording is not None and cmd.record:
            if not self._parts:               # 'walking' stamped just before the first sample
                r = self._records[0]
                t0 = float(part.t_s[0]) - 0.5 / bench.sim.config.rate_hz
                self._records[0] = SessionRecord(t0, *astuple(r)[1:])
            self._parts.append(part)
        return cmd

    def run(self, *, max_sim_s: float = 1e6, stop: Callable[[SequencerCommand], bool] | None
            = None) -> SequencerCommand:
        """Step until the plan is done, ``stop(cmd)`` is true (a simulated crash: nothing more
        is saved) or ``max_sim_s`` of simulated time has passed (RuntimeError)."""
        t_end = self.bench.t_s + max_sim_s
        while self.bench.t_s < t_end:
            cmd = self.step()
            if (cmd.state in ('done', 'aborted') and not cmd.torque) or \
                    (stop is not None and stop(cmd)):
                return cmd
        raise RuntimeError(f'bench plan not finished after {max_sim_s} s of simulated time '
                           f'(state {self.seq.state!r}, temperatures {self.bench.temperatures_c})')

    def _record_transition(self, cmd: SequencerCommand) -> None:
        s = cmd.session
        if self._recording is not None and (not cmd.record or s != self._recording):
            # an abort mid-walk: the session is not counted, its partial bag goes aside
            self._write_bag(aborted=cmd.state == 'aborted')
        if cmd.record and self._recording is None and s is not None:
            self._recording = s
            self._parts = []
            self._records = [SessionRecord(self.bench.t_s, s.session_id, 'walking',
                                           self.bench.load_kg, s.frequency_hz, s.duty_factor,
                                           s.step_length_m, s.step_height_m)]
            self._event('walk', s.session_id)

    def _write_bag(self, *, aborted: bool = False) -> None:
        """Write the session's walk to ``<output_dir>/<session_id>``; an aborted walk's
        partial bag is then moved aside to ``<session_id>.interrupted-N`` (event
        ``interrupted``), as the external backend does, so it is never read as a session."""
        from .sim_bag import write_trace

        s, parts = self._recording, self._parts
        self._recording, self._parts = None, []
        if s is None or not parts or self.output_dir is None:
            return
        path = Path(self.output_dir) / s.session_id
        path.parent.mkdir(parents=True, exist_ok=True)
        move_aside(path)
        write_trace(self.bench.trace(parts, self._records, s), path, storage=self.storage)
        if aborted:
            self._event('interrupted', s.session_id, str(move_aside(path)))
            return
        self._event('bag', s.session_id, str(path))
