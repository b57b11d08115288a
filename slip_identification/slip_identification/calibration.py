"""Self-calibration of the live ``slip_fitter``: ground, stream offset and pitch zero from the
first strides it sees (core; no ROS).

Without a ``ground`` parameter the node used the paper's clock edges and no stream offset, and
its fits were 35-71 % off the offline analysis (stiffness, a simulated EduBot running run).
:class:`SelfCalibration` buffers the samples the node would give its :class:`.online.OnlineSlip`
(joint states with their efforts, joint commands, motion capture, in arrival order) until the
motion capture in the box spans ``strides`` strides (the stride from the hips' net rotation:
2 pi over their median turning speed; a window whose hips do not turn is started again, so a
robot standing before it walks is not calibrated on its standing). It then builds a
:class:`.pipeline.RunData` from them the way the offline reader does
(:func:`.joints.assemble_joint_frames`, :func:`.joints.command_columns`,
:func:`.joints.stamp_order`) and runs ``hexapod-analyze slip``'s own estimators on it
(:func:`.pipeline.analyze_run` with ``calibration_only``: the same world frame, stream offset
chain, ground and pitch zero fits; :func:`calibrate`). A core for the geometric edges with
those values is built and every buffered sample replayed into it in arrival order (a step
after each motion-capture sample, as live), so the stances inside the buffer are fitted with
the calibration, then the samples that came meanwhile, until it has caught up.

That work runs on a worker thread (``background=True``; the geometric fit's compiled kernels
release the GIL): the node keeps taking messages, which are appended to the buffer. The
hand-over: the worker, having caught up under the lock, marks the calibration ``ready``
(``on_ready`` is then called, e.g. a ROS guard condition's trigger); the node's thread takes
the new core, the fits made so far and the samples that came after the worker's last look
(:meth:`SelfCalibration.take`, which replays those few), in that order, and from then on feeds
the core itself. A run the estimators refuse (an error), or one without a geometric ground,
gives a core with today's clock edges (the given stream offset or none), and the reason.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import SlipError
from .fit import SlipFitResult
from .geometry import LegGeometry
from .joints import assemble_joint_frames, command_columns, stamp_order
from .model import SlipModel
from .online import TIME_JUMP_S, OnlineSlip
from .pipeline import RunData, analyze_run
from .preprocess import Box, permissible_mask

__all__ = ['CALIBRATION_STRIDES', 'Calibration', 'SelfCalibration', 'calibrate',
           'run_data_from_samples']

#: strides of motion capture in the box the self-calibration waits for by default: on
#: simulated EduBot runs (4 gaits x seeds 1-3) the offline estimators on the first six strides
#: were within 0.8 ms (offset) and 1.7 mm (ground) of their whole-run values, except one walk
#: whose whole run is itself 90 ms off the truth where its first strides are not
CALIBRATION_STRIDES = 6.0

#: a window whose hips turn slower than this [rad/s] (median over the hips; their speeds
#: integrated, or their angles' net change without speeds) is restarted
MIN_HIP_SPEED_RAD_S = 0.5

#: the streams' names in the time-jump warnings (as the core names them)
STREAMS = {'js': 'joint_states', 'cmd': 'joint_commands', 'mocap': 'mocap/body'}

#: joint-state time [s] kept before the calibration window while it has not started
LEAD_S = 1.0


@dataclass(frozen=True)
class Calibration:
    """What the self-calibration found (``refused`` empty) or why it gave up.

    ``ground_m`` [m] (in the node's world frame, as ``-p ground``), ``offset_s`` [s] (mocap
    clock minus the joint states', as ``-p mocap_offset``), ``pitch_offset_deg`` (as ``-p
    pitch_offset``); ``offset_method`` the offset's source (``'geometry'``, ``'given'``...);
    ``span_s`` the motion capture used [s], ``stride_s`` the stride it was measured in;
    ``compute_s`` the estimators' time [s]; ``notes``, ``warnings`` the analysis' own."""

    ground_m: float = math.nan
    offset_s: float = 0.0
    pitch_offset_deg: float = 0.0
    offset_method: str = ''
    refused: str = ''
    span_s: float = math.nan
    stride_s: float = math.nan
    compute_s: float = math.nan
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.refused

    def line(self) -> str:
        """One log line: the values, as ``-p`` arguments, or the reason."""
        if not self.ok:
            return f'self-calibration refused: {self.refused}'
        return (f'self-calibration from {self.span_s:.2f} s of motion capture '
                f'({self.span_s / self.stride_s:.1f} strides of {self.stride_s:.3f} s) in '
                f'{self.compute_s:.2f} s: -p ground:={self.ground_m:.4f} -p mocap_offset:='
                f'{self.offset_s:.4f} -p pitch_offset:={self.pitch_offset_deg:.2f} (offset '
                f'{self.offset_method}; the `hexapod-analyze slip` estimators)')


def run_data_from_samples(joint_states: Sequence[Any], commands: Sequence[Any],
                          mocap_t_s: Any, mocap_position_m: Any, mocap_quat_xyzw: Any,
                          *, label: str = 'live') -> RunData:
    """:class:`.pipeline.RunData` from samples as the node receives them (JointStateSample-
    like joint states and commands in arrival order; mocap stamps on its own clock), built
    as the offline reader builds a bag's (frames assembled, commands in the joints' order,
    streams in stamp order). No battery (the calibration needs none)."""
    notes: list[str] = []
    joints = assemble_joint_frames(joint_states)
    notes.extend(joints.notes)
    names = joints.names
    ct, cv = command_columns(commands, names, notes)
    ct, cv = stamp_order('/joint_commands', notes, ct, cv)
    mt, mp, mq = stamp_order('/mocap/body', notes, np.asarray(mocap_t_s, dtype=float),
                             np.asarray(mocap_position_m, dtype=float).reshape(-1, 3),
                             np.asarray(mocap_quat_xyzw, dtype=float).reshape(-1, 4))
    empty = np.zeros(0)
    return RunData(joint_names=names, joint_t_s=joints.t_s, joint_velocity=joints.velocity,
                   command_t_s=ct, command_velocity=cv, mocap_t_s=mt, mocap_position_m=mp,
                   mocap_quat_xyzw=mq, battery_t_s=empty, battery_voltage_v=empty,
                   battery_current_a=empty, label=label, joint_effort=joints.effort,
                   joint_position=joints.position, notes=tuple(notes))


def calibrate(run: RunData, *, geometry: LegGeometry, box: Box | None = None,
              model: SlipModel | None = None, offset_s: float | None = None,
              pitch_offset_deg: float | None = None, check_body_up: bool = True,
              starts: str = 'multi') -> Calibration:
    """Ground, stream offset and pitch zero of ``run`` by ``hexapod-analyze slip``'s
    estimators (its defaults: ``--offset auto --edges auto``; ``offset_s`` or
    ``pitch_offset_deg`` given are kept, as ``--offset S`` and ``--pitch-offset DEG`` keep
    them). A refusal (the analysis' error, or no geometric ground) is returned, not raised."""
    t0 = time.perf_counter()
    tm = np.asarray(run.mocap_t_s, dtype=float)
    span = float(tm[-1] - tm[0]) if tm.size else math.nan
    try:
        res = analyze_run(run, model=model, box=box,
                          offset_s='auto' if offset_s is None else float(offset_s),
                          edges='auto', geometry=geometry, position_fit=False,
                          check_body_up=check_body_up,
                          pitch_offset_rad=(None if pitch_offset_deg is None
                                            else math.radians(pitch_offset_deg)),
                          starts=starts, calibration_only=True)
    except (SlipError, ValueError, FloatingPointError, np.linalg.LinAlgError) as err:
        return Calibration(refused=str(err), span_s=span,
                           compute_s=time.perf_counter() - t0)
    dt = time.perf_counter() - t0
    if not math.isfinite(res.ground_m):
        why = next((n for n in res.notes if n.startswith('geometric stance edges')),
                   f'the analysis found no geometric ground (edges {res.edges})')
        return Calibration(refused=why, span_s=span, compute_s=dt, notes=tuple(res.notes))
    return Calibration(ground_m=float(res.ground_m), offset_s=float(res.offset_s),
                       pitch_offset_deg=float(res.frame.get('pitch_offset_deg') or 0.0),
                       offset_method=res.offset_method, span_s=span, compute_s=dt,
                       notes=tuple(res.notes), warnings=tuple(res.warnings))


@dataclass
class _Window:
    """The hips' net rotation since the window started (stride length), per joint."""

    first: dict[str, tuple[float, float]] = field(default_factory=dict)   # name: t, q
    last: dict[str, tuple[float, float]] = field(default_factory=dict)
    turn: dict[str, float] = field(default_factory=dict)   # unwrapped rotation [rad]

    def add(self, t_s: float, names: Sequence[str], position: np.ndarray,
            velocity: np.ndarray) -> None:
        """One joint-state sample: the turn from the speeds when it has them, else from the
        angles (wrapped ones unwrapped)."""
        has_v = len(velocity) == len(names)
        if not has_v and len(position) != len(names):
            return
        for k, n in enumerate(names):
            if not str(n).endswith('_hip'):
                continue
            q = float(position[k]) if len(position) == len(names) else math.nan
            v = float(velocity[k]) if has_v else math.nan
            if not (math.isfinite(v) or math.isfinite(q)):
                continue
            if n not in self.first:
                self.first[n] = self.last[n] = (t_s, q)
                self.turn[n] = 0.0
                continue
            t0, q0 = self.last[n]
            if math.isfinite(v):
                self.turn[n] += v * (t_s - t0)
            elif math.isfinite(q0):
                self.turn[n] += (q - q0 + math.pi) % (2.0 * math.pi) - math.pi
            self.last[n] = (t_s, q)

    def speed(self) -> tuple[float, float]:
        """(median |turning speed| of the hips [rad/s], seconds covered) (NaN, 0: none)."""
        w, span = [], []
        for n, (t0, _) in self.first.items():
            dt = self.last[n][0] - t0
            if dt > 0:
                w.append(abs(self.turn[n]) / dt)
                span.append(dt)
        if not w:
            return math.nan, 0.0
        return float(np.median(w)), float(np.median(span))


class SelfCalibration:
    """The buffer, trigger and hand-over of the live self-calibration (module docs).

    Parameters
    ----------
    strides : float
        Strides of in-box motion capture to buffer before calibrating.
    calibrate_run : callable
        ``RunData -> Calibration`` (e.g. :func:`calibrate` with the node's geometry).
    make_core : callable
        ``Calibration -> OnlineSlip``: the core the buffer is replayed into (geometric edges
        with the calibration's values, or today's when refused).
    box : Box
        The node's box (the window counts motion capture inside it).
    background : bool
        Calibrate and replay on a worker thread (live); False: inline on the caller's thread
        when due (tests, deterministic tools).
    on_ready : callable, optional
        Called (on the worker thread) once the result can be taken (:meth:`take`).
    """

    def __init__(self, strides: float, calibrate_run: Callable[[RunData], Calibration],
                 make_core: Callable[[Calibration], OnlineSlip], *, box: Box | None = None,
                 background: bool = True, on_ready: Callable[[], None] | None = None,
                 time_jump_s: float = TIME_JUMP_S) -> None:
        self.strides = float(strides)
        self._calibrate_run = calibrate_run
        self._make_core = make_core
        self.box = box if box is not None else Box()
        self.background = background
        self.on_ready = on_ready
        self.time_jump_s = time_jump_s
        #: 'collecting', 'calibrating', 'ready' (the worker is done), 'done' (taken)
        self.state = 'collecting'
        self._lock = threading.Lock()
        self._events: list[tuple[Any, ...]] = []
        self._replayed = 0
        self._window = _Window()
        self._first_inside_s: float | None = None   # mocap clock
        self._closed = False
        self._last: dict[str, float] = {}
        self._checked_s = -math.inf
        self._thread: threading.Thread | None = None
        self._core: OnlineSlip | None = None
        self._fits: list[SlipFitResult] = []
        #: backward time jumps while buffering, one line each (the node logs them)
        self.warnings: list[str] = []
        #: errors of samples the replay dropped (the node logs them as dropped messages)
        self.dropped: list[str] = []
        self.result: Calibration | None = None
        #: worker seconds: calibration, then replay of the buffer (until caught up)
        self.replay_s = math.nan
        #: samples in the buffer when it became due, and replayed by the node's thread
        self.buffered = 0
        self.replayed_on_take = 0

    # -- collecting (the node's thread) -------------------------------------------------
    def _jumped(self, stream: str, t_s: float) -> bool:
        last = self._last.get(stream)
        self._last[stream] = t_s if last is None else max(last, t_s)
        return last is not None and t_s < last - self.time_jump_s

    def _restart_window(self, keep_from_s: float | None) -> None:
        """Start the window again: joint-state time from ``keep_from_s`` kept (none: all
        dropped), every motion capture dropped."""
        self._first_inside_s = None
        self._window = _Window()
        if keep_from_s is None:
            self._events = []
            self._last = {}
            return
        kept = [e for e in self._events if e[0] in ('js', 'cmd') and e[1].t_s >= keep_from_s]
        self._events = kept
        for e in kept:
            if e[0] == 'js':
                self._window.add(e[1].t_s, e[1].names, e[1].position, e[1].velocity)

    def offer(self, kind: str, *args: Any) -> bool:
        """Take one sample (``'js'`` or ``'cmd'`` with a JointStateSample, ``'mocap'`` with
        ``t_s, position, quaternion``); False once the calibration is done (the caller feeds
        its core directly). May start the calibration (module docs)."""
        if self.state == 'done':
            return False
        with self._lock:
            if self.state == 'done':
                return False
            if self.state != 'collecting':
                self._events.append((kind, *args))
                return True
            t_s = float(args[0].t_s if kind != 'mocap' else args[0])
            last = self._last.get(kind)
            if self._jumped(kind, t_s):
                self._restart_window(None)   # a looped bag: the window starts again
                self._last[kind] = t_s
                self.warnings.append(
                    f'time jumped back {last - t_s:.3f} s on {STREAMS[kind]} ({last:.3f} s -> '
                    f'{t_s:.3f} s: a looped bag or a reset simulation clock?): the '
                    'self-calibration\'s buffer restarted from the new time')
            due = kind == 'mocap' and self._mocap_due(t_s, args[1])
            self._events.append((kind, *args))
            if kind == 'js':
                self._window.add(t_s, args[0].names, args[0].position, args[0].velocity)
            if self._first_inside_s is None and len(self._events) > 4000:
                # nothing in the box yet: only the last second is kept
                self._restart_window(self._last.get('js', t_s) - LEAD_S)
            if due:
                self.state = 'calibrating'
                self.buffered = len(self._events)
        if due:
            if self.background:
                self._thread = threading.Thread(target=self._work, name='slip_calibration',
                                                daemon=True)
                self._thread.start()
            else:
                self._work()
        return True

    def _mocap_due(self, t_s: float, position: Any) -> bool:
        """Whether the window, with this in-box sample, spans ``strides`` strides (called
        before the sample is buffered: a restart of the window keeps it)."""
        p = np.asarray(position, dtype=float).reshape(1, 3)
        if not np.all(np.isfinite(p)) or not permissible_mask(p, self.box)[0]:
            return False
        if self._first_inside_s is None:
            # the window starts: joint states from just before it; older samples are no use
            self._restart_window(t_s - LEAD_S)
            self._first_inside_s = t_s
            return False
        if t_s - self._checked_s < 0.1:
            return False
        self._checked_s = t_s
        w, covered = self._window.speed()
        if covered >= 1.0 and not w >= MIN_HIP_SPEED_RAD_S:
            # the hips do not turn (standing): the window starts again from here
            self._restart_window(t_s - LEAD_S)
            self._first_inside_s = t_s
            return False
        stride = 2.0 * math.pi / w if w > 0 else math.inf
        return covered >= 0.5 and t_s - self._first_inside_s >= self.strides * stride

    def pending(self) -> str:
        """Why no fit came yet, when the window is still collecting ('' otherwise): the
        motion capture in the box so far against the strides it waits for (the node says it
        when it stops, or when a replayed bag ends, before the calibration was due; it had
        said nothing)."""
        with self._lock:
            if self.state != 'collecting' or not self._events:
                return ''   # (nothing came: the node's input watch says so)
            if self._first_inside_s is None:
                return (f'the self-calibration never started: no motion capture inside the box '
                        f'(it waits for {self.strides:g} strides of it); no stance was fitted')
            w, _ = self._window.speed()
            mocap = self._last.get('mocap', self._first_inside_s)
            tracked = max(mocap - self._first_inside_s, 0.0)
            stride = (f'{tracked * w / (2.0 * math.pi):.1f} strides'
                      if w >= MIN_HIP_SPEED_RAD_S else 'the hips not turning')
            return (f'the self-calibration was not due: its window spans {tracked:.2f} s of '
                    f'motion capture since the robot entered the box ({stride}) of the '
                    f'{self.strides:g} strides it waits for; no stance was fitted. Give ground, '
                    f'mocap_offset and pitch_offset, or lower calibration_strides')

    # -- the worker ------------------------------------------------------------------------
    def _split(self, events: Sequence[tuple[Any, ...]]) -> RunData:
        js = [e[1] for e in events if e[0] == 'js']
        cmd = [e[1] for e in events if e[0] == 'cmd']
        mo = [e for e in events if e[0] == 'mocap']
        return run_data_from_samples(js, cmd, [e[1] for e in mo], [e[2] for e in mo],
                                     [e[3] for e in mo])

    def _work(self) -> None:
        t0 = time.perf_counter()
        with self._lock:
            events = list(self._events)
        w, _ = self._window.speed()
        stride = 2.0 * math.pi / w if w > 0 else math.nan
        try:
            cal = self._calibrate_run(self._split(events))
        except Exception as err:   # noqa: BLE001 - any failure falls back, with its reason
            cal = Calibration(refused=f'{type(err).__name__}: {err}')
        cal = Calibration(**{**cal.__dict__, 'stride_s': stride})
        if self._closed:
            return
        core = self._make_core(cal)
        fits: list[SlipFitResult] = []
        done = 0
        while True:
            with self._lock:
                if self._closed:   # the node is gone: no hand-over, no on_ready
                    return
                new = self._events[done:]
                if not new:
                    self._core, self._fits, self.result = core, fits, cal
                    self._replayed = done
                    self.state = 'ready'
                    self.replay_s = time.perf_counter() - t0
                    # under the lock: close() returns only once this is done, so the node
                    # never destroys what on_ready touches (its guard condition) under it
                    if self.on_ready is not None:
                        self.on_ready()
                    return
            fits.extend(self._replay(core, new))
            done += len(new)

    def _replay(self, core: OnlineSlip, events: Sequence[tuple[Any, ...]]
                ) -> list[SlipFitResult]:
        out: list[SlipFitResult] = []
        for e in events:
            if self._closed:
                break
            try:
                if e[0] == 'js':
                    s = e[1]
                    core.add_joint_state(s.t_s, s.names, s.velocity, s.position)
                elif e[0] == 'cmd':
                    core.add_command(e[1].t_s, e[1].names, e[1].velocity)
                else:
                    core.add_mocap(e[1], e[2], e[3])
                    out.extend(core.step())
            except (ValueError, RuntimeError) as err:   # as the node drops a bad message
                self.dropped.append(str(err))
        return out

    # -- the hand-over (the node's thread) ---------------------------------------------------
    def take(self) -> tuple[OnlineSlip, Calibration, list[SlipFitResult]] | None:
        """Once the worker is done: the new core, the calibration, and every fit so far (the
        buffer's stances, then those of the samples that came meanwhile, replayed here);
        None before (and after the first call)."""
        if self.state != 'ready':
            return None
        with self._lock:
            rest = self._events[self._replayed:]
            core, cal, fits = self._core, self.result, self._fits
            self._events, self._fits, self._core = [], [], None
            self.state = 'done'
        assert core is not None and cal is not None
        self.replayed_on_take = len(rest)
        fits = fits + self._replay(core, rest)
        return core, cal, fits

    def close(self) -> bool:
        """Stop (the node is being destroyed): a running worker stops at its next sample and
        never calls ``on_ready`` (it had called it on the destroyed node's guard condition,
        a traceback, after running on for seconds); True when the result is ready to be
        taken (:meth:`take` still gives it: the fits already computed, to publish)."""
        with self._lock:
            self._closed = True
            return self.state == 'ready'

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for the worker (offline tools, tests); True when it is done or none runs."""
        if self._thread is not None:
            self._thread.join(timeout_s)
            return not self._thread.is_alive()
        return True
