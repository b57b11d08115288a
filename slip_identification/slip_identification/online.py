"""Online stance detection and fitting (core of the ``slip_fitter`` node; no ROS).

Streams are buffered (last ``buffer_s`` seconds). On every :meth:`OnlineSlip.step` the target
edges of each tripod are shifted by the best shift over the buffer (Section 3), single-tripod
stances are formed, and every stance whose lift-off is covered by motion capture (plus
``margin_s``, default 0) and not yet fitted is fitted with the paper's estimator and returned
once. The spline ends at the newest sample with not-a-knot (one-sided) end conditions, so the
fit starts on the first motion-capture sample after lift-off: the data latency is at most one
mocap period (8.3 ms at 120 Hz) plus the compute time. The world frame is built from the
buffered in-box mocap samples and cached (axes refitted every ``frame_every_s`` of data, the
origin kept where the path first entered the volume); only the stance's own window (plus
``spline_pad_s``) is splined, so a step with a fit costs a few ms (bench/bench_slip.py).
The frame needs ``frame_min_s`` of in-box path first and is refitted on every fitting step
until it rests on ``frame_every_s`` of path: over a short path the vertical bounce of the COM
tilts the best-fit line (simulated running: ground normal off by 20-36 deg from 0.15 s of
path, 0.4-1.2 deg from 0.3-0.7 s, 0.1-0.25 deg from 1 s), and the tilt times the distance from
the mocap origin (the ground height) moves the rest length by centimetres (a frame cached
from the first 0.15 s put the first online rest lengths 10-50 mm off the offline ones).
Stances that end before the frame is ready are skipped with reason ``frame_not_ready``.
On a gait whose stride (the hips') is longer than ``frame_min_s`` (the simulated pace and
walk) the geometric edges' frame waits for :data:`FRAME_MIN_STRIDES` strides of path and fits
its line through the path's stride means: from under two strides of a pace the bounce tilted
the line by up to 1 deg, and the first two seconds of single supports were 38-254 ms off the
simulator's (seed 1; now within 8.4 ms); running and jogging are unchanged.

Geometric edges (``geometry`` and ``ground_m`` given, hip angles passed to
:meth:`OnlineSlip.add_joint_state`): the single-support windows come from the half-circle
legs' contacts (:func:`.geometry.leg_contacts` over the last ``geometry_window_s`` of the
buffer, heights above ``ground_m`` in the world frame: the buffered one, or ``world_frame``
when given, e.g. an offline analysis' frame with its ground; the stream offset is
``mocap_offset_s``) instead of the clock's target edges; a window is fitted once the mocap
covers its lift-off (a piece that touches the buffer's newest sample is not yet finished;
stances that end before the world frame is ready are not looked for). A stance overlapping
one fitted or skipped before is never fitted again: a frame refitted on every step while
young swung the ground under a jog by centimetres and moved its first window by 30 ms between
steps, which was fitted twice (an outside review). Waiting for the frame to rest on
``frame_every_s`` of path was tried and left: it put the first stances of clean jogs 3-5 ms
off where the young frame's were within 1.3 ms (a review of the change). Without them, or
without hip angles from the start, the paper's target edges are used (said once in
:attr:`OnlineSlip.warnings`); a step where the contacts cannot be found (hip angles lost,
``leg_contacts`` failing) fits nothing and waits, with a throttled warning (it had fallen back
to the clock's edges without a word).

Other labs' joint states (:class:`.joints.JointFrameAssembler`): messages split over name
groups are assembled, wrapped hip angles are unwrapped per joint as they arrive, and a driver
that publishes positions without velocities gets central-difference speeds, each joint frame
one joint-state period late (10 ms at 100 Hz: the fits, which wait for the motion capture
after lift-off, see at most that much extra latency); :attr:`OnlineSlip.notes` lists what was
done.

Time going backwards (a looped bag restarting, a simulation clock reset): a stream whose stamp
falls more than ``time_jump_s`` behind its own previous stamp restarts everything from the new
time (buffers, joint assemblers, world frame, fitted-stance memory), with one line in
:attr:`OnlineSlip.warnings` naming the jump; samples of the other streams stamped before the
jump that arrive after it are dropped until their own stamps jump. Each loop of a looped bag
gives the same fits; stamps a few ms out of order are unaffected.

Latency bookkeeping (simulated time, no wall clock): for every fit, ``latency_s`` records the
time of the newest motion-capture sample (proprioception clock) minus the stance's lift-off.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from hexapod_common.clocks import StreamClock, foreign_clock_note

from .errors import SlipDataError, SlipError
from .fit import SlipFitResult, SlipFitter, Stance, validate_stance
from .geometry import LegGeometry, body_pitch_rad, leg_contacts, single_support
from .joints import JointFrameAssembler, missing_joints
from .model import SlipModel
from .pipeline import TRIPODS, _tripod_mean, _up_from_quats
from .preprocess import (
    Box,
    WorldFrame,
    fit_world_frame,
    frozen_pose_mask,
    max_mocap_gap_s,
    permissible_mask,
    sagittal_state,
)
from .stance import (
    StanceWindow,
    best_shift,
    edges_from_target,
    open_stance_windows,
    single_tripod_stances,
    tripod_stance_windows,
)

__all__ = ['TIME_JUMP_S', 'OnlineSlip', 'OnlineSkip']

#: a stream's stamp this far [s] behind its previous one is a backward time jump
TIME_JUMP_S = 1.0


class _Rows:
    """Rows in stamp order in preallocated arrays: appended at the end (a row received out of
    stamp order is inserted at its stamp), dropped from the front by stamp; :meth:`step`
    reads the columns as views. (The buffers were deques of
    tuples turned into arrays on every motion-capture message: 2.0 / 5.0 / 8.5 ms a step at
    100 / 500 / 1,000 Hz joint states in a review, a quarter of it building the arrays.)"""

    def __init__(self) -> None:
        self._t = np.empty(0)
        self._cols: tuple[np.ndarray, ...] = ()
        self._a = 0   # first row
        self._b = 0   # one past the last row

    def __len__(self) -> int:
        return self._b - self._a

    def __iter__(self):  # type: ignore[no-untyped-def]
        for i in range(self._a, self._b):
            yield (float(self._t[i]),) + tuple(c[i] for c in self._cols)

    @property
    def t(self) -> np.ndarray:
        return self._t[self._a:self._b]

    def col(self, k: int) -> np.ndarray:
        if not self._cols:   # nothing appended yet
            return np.empty(0)
        return self._cols[k][self._a:self._b]

    def clear(self) -> None:
        self.__init__()  # type: ignore[misc]

    def append(self, t_s: float, *cols: np.ndarray) -> None:
        if not self._cols:
            self._cols = tuple(np.empty((256,) + np.shape(c)) for c in cols)
            self._t = np.empty(256)
        for c, v in zip(self._cols, cols):
            if np.shape(v) != c.shape[1:]:
                raise SlipDataError(f'a row of shape {np.shape(v)} among rows of shape '
                                    f'{c.shape[1:]} (the joint set changed?)')
        if self._b == self._t.size:
            self._make_room()
        k = self._b
        if k > self._a and t_s < self._t[k - 1]:
            # received out of stamp order (another lab's recorder, a multi-threaded
            # executor): inserted at its stamp, after equal ones, as offline sorts it
            k = self._a + int(np.searchsorted(self._t[self._a:self._b], t_s, side='right'))
            self._t[k + 1:self._b + 1] = self._t[k:self._b]
            for c in self._cols:
                c[k + 1:self._b + 1] = c[k:self._b]
        self._t[k] = t_s
        for c, v in zip(self._cols, cols):
            c[k] = v
        self._b += 1

    def _make_room(self) -> None:
        """Move the rows to the front, into arrays twice as large when over half full."""
        n = self._b - self._a
        size = self._t.size if 2 * n <= self._t.size else 2 * self._t.size
        arrays = (self._t,) + self._cols
        out = [a if size == a.shape[0] else np.empty((size,) + a.shape[1:]) for a in arrays]
        for src, dst in zip(arrays, out):
            dst[:n] = src[self._a:self._b]
        self._t, self._cols = out[0], tuple(out[1:])
        self._a, self._b = 0, n

    def trim(self, t_min: float) -> None:
        """Drop rows from the front while they are stamped before ``t_min``."""
        while self._a < self._b and self._t[self._a] < t_min:
            self._a += 1

    def reorder(self, k: int, idx: np.ndarray) -> None:
        """Permute column ``k``'s entries of every row by ``idx``."""
        c = self._cols[k]
        c[self._a:self._b] = c[self._a:self._b][:, idx]


#: a motion-capture gap longer than this many strides is one skip, not placed stances
MAX_GAP_STRIDES = 10


#: a world frame on less than a stride of path (``frame_min_s`` shorter than the hips' stride:
#: the simulated pace and walk) waits for this many strides and fits its line through the
#: path's stride means
FRAME_MIN_STRIDES = 2.5


def _stride_means(t_s: np.ndarray, p: np.ndarray, period_s: float) -> np.ndarray:
    """Means of ``p`` (n, 3) over one ``period_s`` centred on each sample whose period lies
    within ``t_s`` (trapezoids of the samples; a gap is bridged linearly); ``p`` itself when
    fewer than 10 samples have one."""
    if t_s.size < 2:
        return p
    c = np.concatenate([np.zeros((1, p.shape[1])),
                        np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t_s)[:, None], axis=0)])
    ok = (t_s - 0.5 * period_s >= t_s[0]) & (t_s + 0.5 * period_s <= t_s[-1])
    if ok.sum() < 10:
        return p
    a, b = t_s[ok] - 0.5 * period_s, t_s[ok] + 0.5 * period_s
    return np.stack([(np.interp(b, t_s, c[:, j]) - np.interp(a, t_s, c[:, j])) / period_s
                     for j in range(p.shape[1])], axis=1)


@dataclass(frozen=True)
class OnlineSkip:
    """A stance that could not be fitted and why."""

    touchdown_s: float
    liftoff_s: float
    tripod: str
    reason: str


class OnlineSlip:
    """Buffers and the per-stance fit loop.

    Parameters
    ----------
    model : SlipModel
    box : Box
        Permissible box in the mocap frame.
    mocap_offset_s : float
        Seconds subtracted from mocap stamps (stream offset).
    buffer_s, margin_s : float
        History kept; mocap needed after lift-off before fitting.
    shift_every_s : float
        The best shift is recomputed when this much new proprioception has arrived.
    frame_every_s : float
        The world frame's axes are refitted when this much new motion capture has arrived
        (on every fitting step while the frame rests on less than this much path).
    frame_min_s : float
        In-box motion capture [s] needed before the first world frame (earlier stances are
        skipped, reason ``frame_not_ready``).
    geometry : LegGeometry, optional
        Robot description for the geometric edges (module docs); needs ``ground_m``.
    ground_m : float, optional
        Ground height in the world frame (its plane through the mocap origin) [m].
    pitch_offset_rad : float
        The rigid body's pitch zero against the hip line [rad] (an offline analysis'
        ``frame['pitch_offset_deg']``), for the geometric contacts.
    geometry_window_s : float
        Buffer span [s] searched for geometric contacts on each step.
    world_frame : WorldFrame, optional
        A fixed world frame (e.g. the offline analysis' of an earlier run in the same
        volume) instead of the one refitted from the buffer; ``ground_m`` is then in it.
    time_jump_s : float
        A stamp this far [s] behind its stream's previous one restarts everything (module
        docs).
    starts : {'multi', 'paper'}
        The fits' Nelder-Mead starts (:class:`.fit.SlipFitter`).
    """

    def __init__(self, model: SlipModel | None = None, *, box: Box | None = None,
                 mocap_offset_s: float = 0.0, buffer_s: float = 3.0,
                 margin_s: float = 0.0, min_stance_s: float = 0.02,
                 shift_every_s: float = 0.25, frame_every_s: float = 1.0,
                 frame_min_s: float = 0.5, spline_pad_s: float = 0.05,
                 geometry: LegGeometry | None = None, ground_m: float | None = None,
                 geometry_window_s: float = 1.0, pitch_offset_rad: float = 0.0,
                 world_frame: WorldFrame | None = None,
                 time_jump_s: float = TIME_JUMP_S, starts: str = 'multi') -> None:
        if (geometry is None) != (ground_m is None):
            raise SlipError('geometric edges need both geometry and ground_m (or neither)')
        self.geometry = geometry
        self.ground_m = ground_m
        self.pitch_offset_rad = float(pitch_offset_rad)
        self.geometry_window_s = geometry_window_s
        self._geo_since_s: float | None = None
        self.model = model if model is not None else SlipModel()
        self.box = box if box is not None else Box()
        self.mocap_offset_s = mocap_offset_s
        self.buffer_s = buffer_s
        self.margin_s = margin_s
        self.min_stance_s = min_stance_s
        self.starts = starts
        self.fitter = SlipFitter(self.model, starts=starts)  # type: ignore[arg-type]
        self._js = _Rows()      # t, velocity (J,), position (J,)
        self._cmd = _Rows()     # t, target velocity (J,)
        self._mocap = _Rows()   # t, position (3,), quaternion xyzw (4,)
        self.names: tuple[str, ...] = ()
        self._joints = JointFrameAssembler()
        self._cmd_joints = JointFrameAssembler()
        self._cmd_perm: dict[tuple[str, ...], np.ndarray] = {}
        self._early_cmd_names: tuple[str, ...] | None = None
        #: stances fitted or skipped: (tripod, touchdown, lift-off) [s]
        self._done: list[tuple[str, float, float]] = []
        #: occurrences of each throttled warning (logged on the 1st, 10th, 100th ...)
        self._warn_counts: dict[str, int] = {}
        #: the geometric edges have given windows (a later lack of hip angles is transient)
        self._geo_seen = False
        self.skipped: list[OnlineSkip] = []
        #: motion-capture gaps (start, end) [s] not yet looked at (geometric edges)
        self._mocap_gaps: list[tuple[float, float, float]] = []   # start, end, stride
        #: the last fitted stances (tripod, touchdown, lift-off): the stride for the gaps
        self._fitted: deque[tuple[str, float, float]] = deque(maxlen=32)
        self.latency_s: list[float] = []
        self.shift_every_s = shift_every_s
        self._shift_cache: dict[str, tuple[float, float]] = {}
        self.frame_every_s = frame_every_s
        self.frame_min_s = frame_min_s
        self._first_inside_s: float | None = None
        self.spline_pad_s = spline_pad_s
        self._frame: tuple[float, WorldFrame] | None = None
        self.world_frame = world_frame
        if world_frame is not None:
            self._frame = (math.inf, world_frame)
        self.time_jump_s = time_jump_s
        #: events worth a warning (backward time jumps, geometric edges missing), one line
        #: each, in order
        self.warnings: list[str] = []
        #: backward time jumps: (stream, previous stamp, new stamp) [s]
        self.time_jumps: list[tuple[str, float, float]] = []
        self._clk = StreamClock(time_jump_s, self._restart,
                                lambda stream, t: self.warnings.append(
                                    foreign_clock_note(stream, t)))
        self._old_notes: list[str] = []

    def warm_up(self) -> float:
        """Load (or compile, the first time on a machine) the compiled kernels before any data
        comes: one synthetic stance fitted with this core's model and starts, and the
        geometric edges' kernel on a few samples. Nothing of this core's state changes.
        Without it the first live stance paid the loading in its publish latency (a running
        run: 52 ms for that stance's step against 10 ms at most for the others). Returns the
        seconds it took."""
        import time

        from ._geometry_kernels import HAVE_NUMBA, leg_gaps
        from .synthetic import make_stances

        t0 = time.perf_counter()
        stance = make_stances(1, seed=0, model=self.model)[0].stance
        SlipFitter(self.model, starts=self.starts).fit([stance])  # type: ignore[arg-type]
        if self.geometry is not None and HAVE_NUMBA:
            z = np.zeros(2)
            leg_gaps(z, z, np.zeros((2, 1)), z, np.zeros(1), 0.0, 0.0, 0.05, 0.0, 1.0)
        return time.perf_counter() - t0

    @property
    def stale_samples(self) -> int:
        """Samples dropped as stamped before a time jump but arriving after it."""
        return self._clk.stale_samples

    def _restart(self, stream: str, last: float, t: float) -> None:
        """Time went back on ``stream`` from ``last`` to ``t``: start again from ``t``."""
        self.time_jumps.append((stream, last, t))
        self.warnings.append(f'time jumped back {last - t:.3f} s on {stream} ({last:.3f} s -> '
                             f'{t:.3f} s: a looped bag or a reset simulation clock?): stance '
                             'detection restarted from the new time')
        # (the stream clock has started again from t and marked the other streams' stale)
        self._old_notes = self.notes
        self._js.clear()
        self._cmd.clear()
        self._mocap.clear()
        self.names = ()
        self._joints = JointFrameAssembler()
        self._cmd_joints = JointFrameAssembler()
        self._cmd_perm = {}
        self._early_cmd_names = None
        self._done = []
        self._geo_seen = False
        self._mocap_gaps = []
        self._fitted.clear()
        self._shift_cache = {}
        self._first_inside_s = None
        self._geo_since_s = None
        self._frame = (math.inf, self.world_frame) if self.world_frame is not None else None

    def set_model(self, model: SlipModel) -> None:
        """Fit the stances from now on with ``model`` (e.g. another mass)."""
        self.model = model
        self.fitter = SlipFitter(model, starts=self.starts)  # type: ignore[arg-type]

    def _trim(self, buf: _Rows, t: float) -> None:
        buf.trim(t - self.buffer_s)

    @property
    def notes(self) -> list[str]:
        """Input fallbacks so far (hip angles unwrapped, velocities derived), one line each,
        each once, across time jumps (a new list: read only)."""
        if not self._old_notes:
            return self._joints.notes
        return self._old_notes + [n for n in self._joints.notes if n not in self._old_notes]

    def add_joint_state(self, t_s: float, names: tuple[str, ...], velocity: np.ndarray,
                        position: np.ndarray | None = None) -> None:
        """One joint-state message: speeds [rad/s] and, for the geometric edges, angles
        [rad]. Every message goes through :class:`.joints.JointFrameAssembler` (O(J)): a
        message may carry a subset of the joints (one per servo bus or per joint; full frames
        are assembled); angles wrapped into ``[-pi, pi)`` or ``[0, 2 pi)`` are unwrapped per
        joint; without velocities (an empty ``velocity``, positions given) the speeds are
        central differences of the angles and each frame enters one joint-state period
        later (10 ms at 100 Hz). A full message with velocities and no wrap is used as it
        is."""
        if not self._clk.observe('joint_states', t_s):
            return
        for fr in self._joints.add(t_s, names, velocity, position):
            if not self.names:
                self._set_names(fr.names)
            self._append_js(fr.t_s, fr.velocity, fr.position)

    def _append_js(self, t_s: float, velocity: np.ndarray,
                   position: np.ndarray | None) -> None:
        v = np.asarray(velocity, dtype=float)
        q = np.full(v.shape, np.nan) if position is None or len(position) == 0 \
            else np.asarray(position, dtype=float)
        if q.shape != v.shape:
            raise SlipError(f'joint position shape {q.shape} differs from velocity {v.shape}')
        self._js.append(t_s, v, q)
        self._trim(self._js, t_s)

    def _set_names(self, names: tuple[str, ...]) -> None:
        """Fix the joint set; commands buffered before it in another order are reordered."""
        self.names = names
        early = self._early_cmd_names
        if early and early != names and set(early) == set(names):
            idx = np.array([early.index(n) for n in names])
            self._cmd.reorder(0, idx)

    def add_command(self, t_s: float, names: tuple[str, ...], velocity: np.ndarray) -> None:
        """One command message (target speeds [rad/s]); split messages are assembled and
        put in the joint states' name order."""
        if not self._clk.observe('joint_commands', t_s):
            return
        if names == self.names or not self.names and names == self._early_cmd_names \
                or not self.names and self._early_cmd_names is None \
                and not missing_joints(names):
            if not self.names:
                self._early_cmd_names = names
            self._cmd.append(t_s, np.asarray(velocity, dtype=float))
            self._trim(self._cmd, t_s)
            return
        for fr in self._cmd_joints.add(t_s, names, velocity):
            if not self.names:
                continue  # the joint set is not known yet
            perm = self._cmd_perm.get(fr.names)
            if perm is None:
                if set(fr.names) != set(self.names):
                    raise SlipDataError(f'command joint names {fr.names} differ from '
                                        f'{self.names}')
                perm = np.array([fr.names.index(n) for n in self.names])
                self._cmd_perm[fr.names] = perm
            self._cmd.append(fr.t_s, fr.velocity[perm])
            self._trim(self._cmd, fr.t_s)

    def add_mocap(self, t_s: float, position_m: np.ndarray, quat_xyzw: np.ndarray) -> None:
        """One motion-capture pose (stamp on the mocap clock; ``mocap_offset_s`` removed)."""
        # on the joint states' clock from here on: the clock check, the buffer and its trim
        # (trimmed by the raw stamp, a capture clock 3 s ahead lost every sample and one
        # behind grew the buffer without bound: a review of the live node)
        t_s = t_s - self.mocap_offset_s
        if not self._clk.observe('mocap/body', t_s):
            return
        if self.geometry is not None and len(self._mocap) >= 8:
            recent = self._mocap.t[-8:]
            dt = float(np.median(np.diff(recent)))
            if t_s - recent[-1] > max_mocap_gap_s(dt):
                # the stride of the fits before the gap (after it they straddle it)
                self._mocap_gaps.append((float(recent[-1]), float(t_s), self._leg_period_s()))
                del self._mocap_gaps[:-64]
        self._mocap.append(t_s, np.asarray(position_m, dtype=float),
                           np.asarray(quat_xyzw, dtype=float))
        self._trim(self._mocap, t_s)

    def step(self) -> list[SlipFitResult]:
        """Fit every newly completed stance; returns the new fits (possibly empty)."""
        # the clock's commands are needed only for the paper's edges: geometric edges work
        # from hip angles and motion capture alone
        if len(self._js) < 50 or len(self._mocap) < 20 or \
                (self.geometry is None and len(self._cmd) < 50):
            return []
        tj, vj = self._js.t, self._js.col(0)
        tm, pm, qm = self._mocap.t, self._mocap.col(0), self._mocap.col(1)
        windows = {}
        opened = {}
        shifts = {}
        geo_windows = self._geometric_windows(tj, vj, tm, pm, qm)
        if geo_windows is None and len(self._cmd) < 50:
            return []
        tc, vc = self._cmd.t, self._cmd.col(0)
        for tp in ([] if geo_windows is not None else TRIPODS):
            target = _tripod_mean(self.names, vc, tp)
            cached = self._shift_cache.get(tp)
            if cached is not None and tj[-1] - cached[0] < self.shift_every_s:
                shift = cached[1]  # the shift drifts slowly: recompute a few times a second
            else:
                shift = best_shift(tj, _tripod_mean(self.names, vj, tp),
                                   lambda t, a=tc, b=target: np.interp(t, a, b))
                self._shift_cache[tp] = (float(tj[-1]), shift)
            shifts[tp] = shift
            td, lo = edges_from_target(tc + shift, target)
            windows[tp] = tripod_stance_windows(td, lo)
            opened[tp] = open_stance_windows(td, lo)
        candidates = (geo_windows if geo_windows is not None
                      else single_tripod_stances(windows, shifts, open_windows=opened))
        ready = [w for w in candidates
                 if w.liftoff_s + self.margin_s <= tm[-1]
                 and not self._is_done(w.tripod, w.liftoff_s, w.touchdown_s)
                 and w.touchdown_s >= max(tj[0], tm[0])]
        if not ready:
            self._skip_stances_in_gaps(float(tm[-1]))
            return []
        inside = permissible_mask(pm, self.box) & ~frozen_pose_mask(pm, qm)
        if self._first_inside_s is None and np.any(inside):
            self._first_inside_s = float(tm[np.argmax(inside)])
        frame_ready = (self._frame is not None or (
            self._first_inside_s is not None
            and tm[-1] - self._first_inside_s >= self.frame_min_s))
        out: list[SlipFitResult] = []
        stances = []
        frame = None
        ready = self._disjoint(ready)
        for w in ready:
            self._done.append((w.tripod, w.touchdown_s, w.liftoff_s))
            reason = ''
            if inside.sum() < 10:
                reason = 'outside_volume'
            elif w.liftoff_s - w.touchdown_s < self.min_stance_s:
                reason = 'too_short'
            elif not frame_ready:
                reason = 'frame_not_ready'
            else:
                try:
                    frame = frame or self._fit_frame(tm, pm, qm, inside)
                    # spline only this stance's window plus a pad (not-a-knot ends)
                    sel = inside & (tm >= w.touchdown_s - self.spline_pad_s) \
                        & (tm <= w.liftoff_s + self.spline_pad_s)
                    track = sagittal_state(tm[sel], frame.to_world(pm[sel]))
                    t, x, rt, rxz, whole = track.window(w.touchdown_s, w.liftoff_s)
                    if not whole:
                        reason = 'mocap_gap'
                    else:
                        st = Stance(t_s=t, state=x, tripod=w.tripod, raw_t_s=rt, raw_xz_m=rxz)
                        validate_stance(st)
                        stances.append(st)
                except SlipError as err:
                    reason = getattr(err, 'reason', 'bad_data')
            if reason:
                self.skipped.append(OnlineSkip(w.touchdown_s, w.liftoff_s, w.tripod, reason))
        if stances:
            out = self.fitter.fit(stances).results_
            self.latency_s.extend(float(tm[-1]) - r.liftoff_s for r in out)
            self._fitted.extend((r.tripod, r.touchdown_s, r.liftoff_s) for r in out)
        self._skip_stances_in_gaps(float(tm[-1]))
        if len(self._done) > 64:
            del self._done[:-64]
        return out

    def _geometric_windows(self, tj: np.ndarray, vj: np.ndarray, tm: np.ndarray,
                           pm: np.ndarray, qm: np.ndarray) -> list[StanceWindow] | None:
        """Single-support windows from the legs' geometric contacts ending after the world
        frame became ready (none before), or None: no geometry, or no hip angles yet (the
        target edges are used, with a warning). Too little data, hip angles missing after
        the geometric edges had worked, or contacts that cannot be found give no windows
        this step (a throttled warning): the stances wait for the geometric edges. (Every
        None had made that step fall back to the clock's edges without a word, and a window
        fitted on them overlapped the geometric one fitted later: an outside review.)"""
        if self.geometry is None or self.ground_m is None:
            return None
        t0 = tj[-1] - self.geometry_window_s
        sj = tj >= t0
        q = self._js.col(1)[sj]
        if not np.all(np.isfinite(q)):
            if not self._geo_seen:
                self._warn_throttled(
                    'no_hip_angles', 'geometric stance edges need hip angles (joint_states '
                    "positions), and the last second has none: the paper's clock edges "
                    '(shifted target edges) are used until they come', once=True)
                return None
            self._warn_throttled(
                'hip_angles_lost', 'hip angles (joint_states positions) missing in the last '
                'second: no geometric stance edges until they are back (stances wait)')
            return []
        inside = permissible_mask(pm, self.box) & ~frozen_pose_mask(pm, qm)
        if self._first_inside_s is None and np.any(inside):
            self._first_inside_s = float(tm[np.argmax(inside)])
        if self._frame is None and (self._first_inside_s is None or tm[-1]
                                    - self._first_inside_s < self._frame_min_path_s()):
            return []  # stances ending before the frame is ready are not looked for
        if self._geo_since_s is None:
            self._geo_since_s = float(tm[-1])
        sm = inside & (tm >= t0 - 0.05)
        if sm.sum() < 20 or sj.sum() < 10:
            return []   # out of the box or a gap (counted by _skip_stances_in_gaps)
        frame = self._world_frame(tm, pm, qm, inside)
        z = frame.to_world(pm[sm])[:, 2]
        pitch = body_pitch_rad(frame.rotation, qm[sm])
        try:
            contacts, unknown = leg_contacts(self.geometry, self.names, tj[sj], q, vj[sj],
                                             tm[sm], z, pitch, offset_s=0.0,
                                             ground_m=self.ground_m,
                                             pitch_offset_rad=self.pitch_offset_rad)
        except SlipError as err:
            self._warn_throttled('leg_contacts', f'geometric stance edges not found: {err} '
                                 '(no stance fitted until they are)')
            return []
        self._geo_seen = True
        ss = single_support(contacts, TRIPODS, unknown)
        return sorted((StanceWindow(float(a), float(b), tp, 0.0)
                       for tp, iv in ss.items() for a, b in iv if b >= self._geo_since_s),
                      key=lambda w: w.touchdown_s)

    def _skip_stances_in_gaps(self, newest_s: float) -> None:
        """Single supports a motion-capture gap cuts or hides, skipped once each, reason
        ``mocap_gap`` (geometric edges need the body's height, so they give none there; they
        had been left out without a word).

        Once each tripod has a fit after the gap (or two strides have passed), its stances
        missing between its last fit before the gap and its first fit after it are placed
        evenly between the two (their number from the stride the hips turn at,
        :meth:`_leg_period_s`, when the gap began), so a speed change across the
        gap and the stances lost next to it (contacts need mocap either side) are counted
        too. Without a fit before the gap, fits not one per stride (a pace's split single
        supports: its lost stances can then go uncounted), or a gap of more than
        :data:`MAX_GAP_STRIDES` strides (the robot out of the volume, standing), the gap
        itself is one skip (tripod '')."""
        if self.geometry is None:
            return
        while self._mocap_gaps:
            a, b, stride = self._mocap_gaps[0]
            fitted_after = {t for t, td, _ in self._fitted if td > b}
            if not (fitted_after >= set(TRIPODS) or not stride > 0
                    or newest_s >= b + 2.0 * stride):
                break
            self._mocap_gaps.pop(0)
            if self._geo_since_s is None or b < self._geo_since_s:
                continue
            placed = False
            for tp in TRIPODS if 0 < stride and (b - a) <= MAX_GAP_STRIDES * stride else ():
                seen = sorted((td, lo) for t, td, lo in self._fitted if t == tp)
                before = [w for w in seen if w[0] < a]
                after = [w for w in seen if w[0] > b]
                if not before:
                    continue
                t0 = before[-1][0]
                if len(before) >= 2 and abs((t0 - before[-2][0]) / stride
                                            - round((t0 - before[-2][0]) / stride)) > 0.25:
                    continue        # the fits are not one per stride here (split stances)
                placed = True
                dur = float(np.median([lo - td for td, lo in seen]))
                if after:       # between the fits either side: a speed change is spread
                    n = int(round((after[0][0] - t0) / stride))
                    tds = [t0 + k * (after[0][0] - t0) / n for k in range(1, n)]
                else:           # none fitted after it yet: the stride up to the gap's end
                    tds = list(np.arange(t0 + stride, b, stride))
                for td in tds:
                    if not self._is_done(tp, td + dur, td):
                        self._done.append((tp, td, td + dur))
                        self.skipped.append(OnlineSkip(td, td + dur, tp, 'mocap_gap'))
            if not placed:
                self.skipped.append(OnlineSkip(a, b, '', 'mocap_gap'))

    def _leg_period_s(self) -> float:
        """The stride period [s] from the hips: a RHex-class leg turns once a stride, so
        2 pi over its mean angular speed over the buffer (the legs' median); NaN when the
        legs do not turn. (From the fitted touchdowns, split single supports 75 ms apart
        had made a pace's 0.575 s stride read 0.077 s and one gap 31 skips; an outside
        review.)"""
        if len(self._js) < 50:
            return math.nan
        t = self._js.t
        v = self._js.col(0)
        span = float(t[-1] - t[0])
        if not span > 0:
            return math.nan
        w = np.abs(np.nanmean(v, axis=0))
        w = float(np.median(w[np.isfinite(w)])) if np.any(np.isfinite(w)) else math.nan
        return 2.0 * math.pi / w if w > 0.5 else math.nan

    def _fit_frame(self, tm: np.ndarray, pm: np.ndarray, qm: np.ndarray,
                   inside: np.ndarray) -> WorldFrame:
        """The frame the stances are fitted in: the world frame, lowered to the ground when
        the geometric edges give it (``ground_m`` over the buffered frame), as the offline
        analysis puts the ground at z = 0. Heights from the mocap origin's plane made every
        online rest length the ground height too long (12.4 mm, 11 % of l0: a review of the
        live node). A given ``world_frame`` is used as it is."""
        frame = self._world_frame(tm, pm, qm, inside)
        if self.ground_m is None or self.world_frame is not None:
            return frame
        rot = np.asarray(frame.rotation, dtype=float)
        origin = np.asarray(frame.origin_m, dtype=float) + self.ground_m * rot[2]
        return WorldFrame(rotation=rot, origin_m=origin)

    def _world_frame(self, tm: np.ndarray, pm: np.ndarray, qm: np.ndarray,
                     inside: np.ndarray) -> WorldFrame:
        """The buffered world frame, refitted when ``frame_every_s`` of new mocap arrived."""
        young = (self._first_inside_s is not None and self._frame is not None
                 and self._frame[0] - self._first_inside_s < self.frame_every_s)
        if self.world_frame is not None:
            return self.world_frame
        if self._frame is None or young or tm[-1] - self._frame[0] >= self.frame_every_s:
            path = pm[inside]
            period = self._slow_stride_s()
            means = math.isfinite(period)
            if means:
                # a slow gait: the path's stride means (the bounce over a part of a stride
                # tilted the line: a pace's first 0.5-1 s up to 1 deg, the heights 15 mm off
                # a metre from the mocap origin)
                path = _stride_means(tm[inside], path, period)
            frame = fit_world_frame(path, up_mocap=_up_from_quats(qm[inside]))
            if self._frame is None and means:
                # the origin where the path entered the volume (foot_x), as without the means
                p0 = pm[inside][0]
                n = frame.rotation[2]
                frame = WorldFrame(rotation=frame.rotation, origin_m=p0 - (p0 @ n) * n)
            if self._frame is not None:
                # keep the origin where the path first entered the volume: foot_x stays in
                # one frame for the whole run; only the axes are refined
                old = self._frame[1].origin_m
                n = frame.rotation[2]
                frame = WorldFrame(rotation=frame.rotation,
                                   origin_m=old - ((old - frame.origin_m) @ n) * n)
            self._frame = (float(tm[-1]), frame)
        return self._frame[1]

    def _slow_stride_s(self) -> float:
        """The hips' stride [s] when ``frame_min_s`` holds less than one (a slow gait whose
        first path line the bounce tilts), else NaN."""
        period = self._leg_period_s() if self.geometry is not None else math.nan
        return period if math.isfinite(period) and self.frame_min_s < period else math.nan

    def _frame_min_path_s(self) -> float:
        """In-box path [s] the geometric edges' world frame needs: ``frame_min_s``, on a slow
        gait (:meth:`_slow_stride_s`) :data:`FRAME_MIN_STRIDES` strides."""
        period = self._slow_stride_s()
        return FRAME_MIN_STRIDES * period if math.isfinite(period) else self.frame_min_s

    def _is_done(self, tripod: str, liftoff_s: float,
                 touchdown_s: float | None = None) -> bool:
        """A stance of ``tripod`` fitted or skipped with a lift-off within 30 ms (the shift
        over the moving buffer may move an edge by a few ms between steps) or overlapping
        ``touchdown_s``-``liftoff_s``: two fits for one stance are never published."""
        td = liftoff_s if touchdown_s is None else touchdown_s
        return any(tp == tripod and (abs(lo - liftoff_s) < 0.03 or min(lo, liftoff_s)
                                     > max(a, td))
                   for tp, a, lo in self._done)

    @staticmethod
    def _disjoint(windows: list[StanceWindow]) -> list[StanceWindow]:
        """``windows`` without those overlapping an earlier one of the same tripod."""
        out: list[StanceWindow] = []
        for w in windows:
            if not any(o.tripod == w.tripod and min(o.liftoff_s, w.liftoff_s)
                       > max(o.touchdown_s, w.touchdown_s) for o in out):
                out.append(w)
        return out

    def _warn_throttled(self, key: str, text: str, *, once: bool = False) -> None:
        """Append ``text`` to :attr:`warnings` on its 1st, 10th, 100th ... occurrence (on
        its first alone with ``once``)."""
        n = self._warn_counts[key] = self._warn_counts.get(key, 0) + 1
        if n == 1 or not once and (n in (10, 100, 1000) or n % 10000 == 0):
            self.warnings.append(text if n == 1 else f'{text} [{n} steps so far]')
