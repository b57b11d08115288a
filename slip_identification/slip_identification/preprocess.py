"""Section 3 preprocessing of Komsuoglu et al.: synchronisation, resampling, world frame.

Steps (each a function, composed by :func:`preprocess_run`):

1. :func:`estimate_offset` -- clock offset between two streams by maximising the normalised
   cross-correlation of two signals that move together (default in the pipeline: the
   mocap body's vertical velocity against the proprioceptive tripod speed difference
   ``mean(left hips) - mean(right hips)``, both oscillating at the stepping frequency), found on
   a 1 ms grid and refined by a parabola through the peak. A constant physical lag between the
   two signals is indistinguishable from a clock offset; pass ``lag_s`` (calibrated once on a run
   with a known offset) to remove it. The paper measured its offset; this is the data-driven
   substitute.
2. :func:`permissible_mask` -- keep samples inside the permissible box (mocap frame).
3. :func:`fit_world_frame` -- ground normal from the mean body attitude (or, without it, the
   mocap z axis made orthogonal to the path), ground height from the mocap origin (Vicon
   calibrates its origin on the floor) or from ``com_height_m``, origin where the COM path
   enters the permissible box, x along the best-fit line of the horizontal COM path in the
   direction of travel.
4. :func:`check_straight` -- refuse runs whose horizontal path deviates from its line.
5. :func:`sagittal_state` -- cubic spline per continuous segment (gaps in mocap split it),
   sampled at 1 kHz with its derivative: ``[bx, bx', bz, bz']``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from .errors import SlipDataError

__all__ = [
    'Box',
    'SagittalTrack',
    'WorldFrame',
    'check_straight',
    'estimate_offset',
    'fit_world_frame',
    'frozen_pose_mask',
    'permissible_mask',
    'resample_cubic',
    'sagittal_state',
    'walks_backwards',
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Box:
    """Axis-aligned permissible box in the mocap frame [m] (paper: 2 x 1 x 1 m)."""

    lower_m: tuple[float, float, float] = (-1.0, -0.5, -0.5)
    upper_m: tuple[float, float, float] = (1.0, 0.5, 0.5)


@dataclass(frozen=True)
class WorldFrame:
    """Run-specific world frame: ``p_world = R @ (p_mocap - origin_m)``.

    ``rotation`` rows are the world x, y, z axes expressed in the mocap frame.
    """

    rotation: FloatArray  # (3, 3)
    origin_m: FloatArray  # (3,) in the mocap frame, on the ground plane

    def to_world(self, p_mocap_m: ArrayLike) -> FloatArray:
        """(n, 3) mocap positions -> (n, 3) world positions."""
        p = np.atleast_2d(np.asarray(p_mocap_m, dtype=float))
        return (p - self.origin_m) @ self.rotation.T

    @property
    def tilt_rad(self) -> float:
        """Angle between the ground normal and the mocap z axis."""
        return float(np.arccos(np.clip(self.rotation[2, 2], -1.0, 1.0)))

    @property
    def yaw_rad(self) -> float:
        """Heading of the world x axis in the mocap xy plane."""
        return float(np.arctan2(self.rotation[0, 1], self.rotation[0, 0]))


def estimate_offset(t_a_s: ArrayLike, a: ArrayLike, t_b_s: ArrayLike, b: ArrayLike, *,
                    max_offset_s: float = 0.2, step_s: float = 1e-3,
                    lag_s: float = 0.0) -> float:
    """Offset ``d`` such that ``b(t + d)`` best matches ``a(t)`` (stream b is late by d).

    Both signals are resampled (linear) on a common grid, demeaned, and the normalised
    cross-correlation is maximised over ``|d| <= max_offset_s`` on a ``step_s`` grid, then refined
    by a parabola through the peak. ``lag_s`` is subtracted (known physical lag).

    Returns
    -------
    float
        Offset [s]; subtract it from stream b's times to align b with a.
    """
    ta = np.asarray(t_a_s, dtype=float)
    tb = np.asarray(t_b_s, dtype=float)
    ya = np.asarray(a, dtype=float)
    yb = np.asarray(b, dtype=float)
    ok_a = np.isfinite(ya) & np.isfinite(ta)
    ok_b = np.isfinite(yb) & np.isfinite(tb)
    ta, ya, tb, yb = ta[ok_a], ya[ok_a], tb[ok_b], yb[ok_b]
    if ta.size < 10 or tb.size < 10:
        raise SlipDataError('estimate_offset needs >= 10 finite samples in each stream')
    lo = max(ta[0], tb[0] - max_offset_s) + max_offset_s
    hi = min(ta[-1], tb[-1] + max_offset_s) - max_offset_s
    if hi - lo < 4 * max_offset_s:
        raise SlipDataError(
            f'streams overlap for {hi - lo:.3f} s, need >= {4 * max_offset_s:.3f} s to estimate '
            'the offset')
    grid = np.arange(lo, hi, step_s)
    sa = np.interp(grid, ta, ya)
    sa = (sa - sa.mean()) / (sa.std() + 1e-300)
    shifts = np.arange(-max_offset_s, max_offset_s + 0.5 * step_s, step_s)
    score = np.empty(shifts.size)
    for i, d in enumerate(shifts):
        sb = np.interp(grid + d, tb, yb)
        sb = (sb - sb.mean()) / (sb.std() + 1e-300)
        score[i] = np.mean(sa * sb)
    i = int(np.argmax(score))
    d = shifts[i]
    if 0 < i < shifts.size - 1:
        y0, y1, y2 = score[i - 1], score[i], score[i + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            d += 0.5 * step_s * (y0 - y2) / den
    return float(d - lag_s)


def permissible_mask(p_mocap_m: ArrayLike, box: Box) -> NDArray[np.bool_]:
    """True for finite samples inside the box, shape (n,)."""
    p = np.asarray(p_mocap_m, dtype=float)
    lo = np.asarray(box.lower_m)
    hi = np.asarray(box.upper_m)
    return np.all(np.isfinite(p), axis=1) & np.all((p >= lo) & (p <= hi), axis=1)


#: a pose repeated exactly this many times in a row (the first sample of the run besides) is
#: a motion-capture bridge repeating its last pose after losing the body
FROZEN_POSE_REPEATS = 2


def frozen_pose_mask(p_mocap_m: ArrayLike, quat_xyzw: ArrayLike | None = None, *,
                     min_repeats: int = FROZEN_POSE_REPEATS) -> NDArray[np.bool_]:
    """True for samples that repeat the previous sample's pose exactly (position, and the
    quaternion when given) in a run of at least ``min_repeats`` such repeats, shape (n,).

    A bridge that loses the rigid body may go on publishing its last pose (VRPN servers do)
    instead of nothing or NaN; real tracking never repeats a pose to the last bit (its noise
    is tens of micrometres). Those samples are missing data: a stance across them is a
    mocap gap. Before, they were taken as a body standing still in mid-stride (three 0.15 s
    freezes in a simulated jogging run: two stances with nerr up to 0.48 against 0.07 and the
    mean stiffness 14 % low, with no note).
    """
    p = np.asarray(p_mocap_m, dtype=float)
    cols = [p.reshape(len(p), -1)]
    if quat_xyzw is not None:
        cols.append(np.asarray(quat_xyzw, dtype=float).reshape(len(p), -1))
    x = np.hstack(cols)
    same = np.zeros(len(x), dtype=bool)
    if len(x) > 1:
        same[1:] = np.all(x[1:] == x[:-1], axis=1)
    out = np.zeros(len(x), dtype=bool)
    # runs of repeats: mark those at least min_repeats long
    edges = np.flatnonzero(np.diff(np.concatenate(([0], same.astype(np.int8), [0]))))
    for a, b in zip(edges[::2], edges[1::2]):
        if b - a >= min_repeats:
            out[a:b] = True
    return out


def fit_world_frame(p_mocap_m: ArrayLike, *, up_mocap: ArrayLike | None = None,
                    com_height_m: float | None = None, backwards: bool = False
                    ) -> WorldFrame:
    """World frame from the COM path inside the permissible box (time-ordered, (n, 3)).

    A straight run's COM path is (nearly) a line, so it fixes the travel direction and its
    slope but not the roll of the ground about it. The ground normal therefore comes from the
    body attitude when given (``up_mocap``: the mean body z axis in the mocap frame, e.g. from
    the pose quaternions; the body rolls about level on flat ground, and its mean pitch is
    removed by orthogonalising against the path direction); otherwise it
    is the mocap z axis made orthogonal to the path (corrects tilt along the travel direction
    only).

    Parameters
    ----------
    p_mocap_m : array_like, shape (n, 3)
        COM positions in the mocap frame, inside the box, in time order.
    up_mocap : array_like, shape (3,), optional
        Ground normal estimate in the mocap frame.
    com_height_m : float, optional
        Mean COM height above the ground; default: the ground plane passes through the
        mocap origin (Vicon calibrates its origin on the floor).
    backwards : bool
        The robot walks backwards (:func:`walks_backwards`): x points against the travel,
        along the robot's heading, so that its front hips lie at +x and its speed is negative.
    """
    p = np.asarray(p_mocap_m, dtype=float)
    p = p[np.all(np.isfinite(p), axis=1)]
    if p.shape[0] < 10:
        raise SlipDataError(f'world frame needs >= 10 COM samples inside the box, got {p.shape[0]}')
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    direction = vt[0] if (p[-1] - p[0]) @ vt[0] >= 0 else -vt[0]
    if backwards:
        direction = -direction
    if up_mocap is not None:
        # the body's mean pitch tilts its z axis along the path: keep only the part of the
        # attitude normal orthogonal to the (level) direction of travel
        normal = np.asarray(up_mocap, dtype=float)
        normal = normal - (normal @ direction) * direction
        normal = normal / np.linalg.norm(normal)
    else:
        normal = np.array([0.0, 0.0, 1.0]) - direction[2] * direction
        normal /= np.linalg.norm(normal)
    if normal[2] < 0:
        normal = -normal
    h0 = float(normal @ c - com_height_m) if com_height_m is not None else 0.0
    x_axis = direction - (direction @ normal) * normal
    x_axis /= np.linalg.norm(x_axis)
    y_axis = np.cross(normal, x_axis)
    rot = np.vstack([x_axis, y_axis, normal])
    origin = p[0] - (p[0] @ normal - h0) * normal
    return WorldFrame(rotation=rot, origin_m=origin)


def check_straight(p_world_m: ArrayLike, *, max_lateral_m: float = 0.05) -> float:
    """Largest lateral deviation |y| of the path; raise if above ``max_lateral_m``."""
    p = np.asarray(p_world_m, dtype=float)
    dev = float(np.max(np.abs(p[:, 1]))) if p.size else 0.0
    if dev > max_lateral_m:
        raise SlipDataError(
            f'run is not straight: lateral deviation {dev:.3f} m > max_lateral_m '
            f'{max_lateral_m:.3f} m')
    return dev


#: motion-capture gaps up to this long [s] (or :data:`MOCAP_GAP_INTERVALS` sample intervals
#: when longer) are bridged by the cubic spline: two missing samples at 120 Hz, one at 60 Hz
MOCAP_BRIDGE_S = 0.03
#: a gap of at most this many nominal sample intervals is always bridged (one missing sample)
MOCAP_GAP_INTERVALS = 2.5


def max_mocap_gap_s(dt_s: float) -> float:
    """The longest motion-capture gap [s] the cubic spline bridges at sample interval ``dt_s``.

    Samples missing inside it, NaN or never published, are interpolated alike; a longer gap
    splits the track and a stance it touches is left out (``mocap_gap``). Before, only one
    missing sample was bridged: 10 % of the poses NaN (or missing) at random left 0-4 of 15
    stances of a simulated EduBot running run out, which moved the median stiffness by up to
    11 % (rms 4.9 % over ten draws; the stances' median has a 5.1 % standard error).
    """
    return max(MOCAP_GAP_INTERVALS * float(dt_s), MOCAP_BRIDGE_S)


def resample_cubic(t_s: ArrayLike, y: ArrayLike, t_new_s: ArrayLike, *, derivative: int = 0
                   ) -> FloatArray:
    """Cubic spline through ``(t_s, y)`` (y (n,) or (n, k)) evaluated at ``t_new_s``."""
    return np.asarray(CubicSpline(np.asarray(t_s, float), np.asarray(y, float))(
        np.asarray(t_new_s, float), derivative))


@dataclass(frozen=True)
class SagittalTrack:
    """1 kHz sagittal state of a run with the raw samples it came from.

    ``t_s`` (N,), ``state`` (N, 4) ``[bx, bx', bz, bz']``; ``segment`` (N,) index of the
    continuous mocap segment each sample lies in (-1 where no data); ``raw_t_s`` (n,),
    ``raw_xz_m`` (n, 2) world-frame raw samples; ``raw_segment`` (n,).
    """

    t_s: FloatArray
    state: FloatArray
    segment: NDArray[np.int_]
    raw_t_s: FloatArray
    raw_xz_m: FloatArray
    raw_segment: NDArray[np.int_]

    def window(self, t0_s: float, t1_s: float) -> tuple[FloatArray, FloatArray, FloatArray,
                                                        FloatArray, bool]:
        """Samples in [t0, t1]: t, state, raw_t, raw_xz, and whether one segment covers it."""
        k = (self.t_s >= t0_s - 1e-9) & (self.t_s <= t1_s + 1e-9)
        r = (self.raw_t_s >= t0_s - 1e-9) & (self.raw_t_s <= t1_s + 1e-9)
        seg = self.segment[k]
        whole = bool(seg.size > 0 and seg[0] >= 0 and np.all(seg == seg[0])
                     and self.t_s[k][0] - t0_s < 1.5e-3 and t1_s - self.t_s[k][-1] < 1.5e-3)
        return self.t_s[k], self.state[k], self.raw_t_s[r], self.raw_xz_m[r], whole


def sagittal_state(t_s: ArrayLike, p_world_m: ArrayLike, *, rate_hz: float = 1000.0,
                   max_gap_s: float | None = None) -> SagittalTrack:
    """Spline-resampled sagittal state from world-frame positions (n, 3) at times (n,).

    A gap longer than ``max_gap_s`` (default :func:`max_mocap_gap_s` of the nominal sample
    interval) splits the track into segments, each splined on its own; no sample is
    interpolated across such a gap (shorter ones are bridged).
    """
    t = np.asarray(t_s, dtype=float)
    p = np.asarray(p_world_m, dtype=float)
    ok = np.isfinite(t) & np.all(np.isfinite(p), axis=1)
    t, p = t[ok], p[ok]
    if t.size < 4:
        raise SlipDataError(f'sagittal_state needs >= 4 finite samples, got {t.size}')
    dt = np.diff(t)
    if np.any(dt <= 0):
        order = np.argsort(t, kind='stable')
        t, p = t[order], p[order]
        keep = np.concatenate([[True], np.diff(t) > 0])
        t, p = t[keep], p[keep]
        dt = np.diff(t)
    gap = max_gap_s if max_gap_s is not None else max_mocap_gap_s(float(np.median(dt)))
    breaks = np.flatnonzero(dt > gap)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks + 1, [t.size]])
    step = 1.0 / rate_hz
    grid = np.arange(np.ceil(t[0] / step) * step, t[-1] + 0.5 * step, step)
    state = np.full((grid.size, 4), np.nan)
    segment = np.full(grid.size, -1)
    raw_segment = np.empty(t.size, dtype=int)
    for s_i, (a, b) in enumerate(zip(starts, ends)):
        raw_segment[a:b] = s_i
        if b - a < 4:
            continue
        k = (grid >= t[a]) & (grid <= t[b - 1])
        sx = CubicSpline(t[a:b], p[a:b, 0])
        sz = CubicSpline(t[a:b], p[a:b, 2])
        g = grid[k]
        state[k] = np.column_stack([sx(g), sx(g, 1), sz(g), sz(g, 1)])
        segment[k] = s_i
    return SagittalTrack(t_s=grid, state=state, segment=segment, raw_t_s=t,
                         raw_xz_m=p[:, [0, 2]], raw_segment=raw_segment)


#: the rigid body's heading must point within this angle [deg] of against the travel (and
#: every hip turn backwards) for a run to be read as walking backwards
BACKWARDS_MAX_ANGLE_DEG = 60.0


def walks_backwards(p_mocap_m: ArrayLike, quat_xyzw: ArrayLike, hip_net_rad: ArrayLike
                    ) -> tuple[bool, float]:
    """Whether a robot walks backwards: its body moves against its heading.

    The heading is the rigid body's x axis (horizontal part, mean over the run), the motion
    the COM path's end minus its start, and the hips' net rotation over the run
    (``hip_net_rad``, last minus first unwrapped angle per hip) its proprioceptive sign: a
    robot walking backwards turns every hip backwards (net below -pi) while its body moves
    within :data:`BACKWARDS_MAX_ANGLE_DEG` of against its heading. Either sign alone is not
    enough: a rigid body created facing backwards (any yaw is allowed) moves against its x
    axis on a robot walking forward, and hips whose motors are mounted mirrored turn
    backwards on one too.

    Returns
    -------
    (bool, float)
        Backwards or not, and the angle [deg] between the heading and the travel (NaN when
        either is undefined).
    """
    p = np.asarray(p_mocap_m, dtype=float)
    p = p[np.all(np.isfinite(p), axis=1)]
    q = np.atleast_2d(np.asarray(quat_xyzw, dtype=float))
    q = q[np.all(np.isfinite(q), axis=1)]
    net = np.asarray(hip_net_rad, dtype=float)
    net = net[np.isfinite(net)]
    if len(p) < 2 or not len(q):
        return False, float('nan')
    travel = p[-1] - p[0]
    travel[2] = 0.0
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    head = np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)]
                           ).mean(axis=0)
    head[2] = 0.0
    nt, nh = float(np.linalg.norm(travel)), float(np.linalg.norm(head))
    if nt < 0.05 or nh < 0.5:   # no travel, or a rigid body's x axis far from horizontal
        return False, float('nan')
    angle = float(np.degrees(np.arccos(np.clip(travel @ head / (nt * nh), -1.0, 1.0))))
    back = bool(net.size and np.all(net < -np.pi)
                and angle > 180.0 - BACKWARDS_MAX_ANGLE_DEG)
    return back, angle
