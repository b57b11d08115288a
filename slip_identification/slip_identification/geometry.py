"""Contact, ground height and stream offset from the half-circle leg's geometry (RHex class).

A RHex leg is a half circle of arc radius ``R`` with the hip at one end. With the shaft angle
``psi`` from the true vertical (hip angle + body pitch + the hip's zero, toe behind the hip when
positive), the rest-shape height of the leg's lowest point below the hip is

* ``2 R cos(psi)`` for toe contact (``psi < 0``, the toe is the lowest point), and
* ``R (1 + cos(psi))`` while the arc rolls (``0 <= psi < pi``),

and a leg touches the ground iff its hip is lower above the ground than that rest height; it
lifts off when the hip rises back above it (its radial force vanishes). The rest height changes
fast in the clock's fast phase, so lift-off is a sharp crossing there. Hip heights come from
the motion-capture COM height and pitch and the hips' places on the body
(:class:`LegGeometry`, the robot description).

Ground height and stream offset (:func:`fit_ground_offset`): the ground is not visible to the
motion capture, and the mocap clock is offset from the proprioception clock. Both are fitted to
the body's vertical motion: in proprioception time, every leg's penetration
``p_j(t) = max(0, rest_j(t) - hip height_j(t))`` follows from the hip angles and the mocap body
(shifted by the offset ``d``, lowered by the ground height ``g``); the vertical dynamics
``m (z'' + g) = k_w sum_j p_j + c sum_j p_j'`` (a stiffness per window of ``window_s``, one
damping for the run) integrated twice, plus a free height and velocity per window, is linear in
its coefficients for given ``(d, g)``; ``(d, g)`` minimise the residual sum of squares (coarse
grid, then Nelder-Mead). The hip angles move fast in the fast phase, so contact timing -- and
with it ``d`` -- is well determined; ``g`` is fixed by where contacts begin and end.

Measured on simulated EduBot runs (figures in test/unit/test_slip_geometry.py and the report):
offset within about 1 ms, ground height within 1-4 mm (biased high: the leg's bending and the
rolling contact keep the real leg on the ground about 1.5 ms past the rest-shape crossing), and
touchdown/lift-off within 5 ms of the simulator's truth.

Core module: numpy/scipy only (does not import the simulator: pass its parameters to
:meth:`LegGeometry.from_params`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicHermiteSpline, CubicSpline
from scipy.optimize import minimize, minimize_scalar

from .errors import SlipDataError

__all__ = [
    'GeometryFit',
    'LegGeometry',
    'body_pitch_rad',
    'fit_ground_offset',
    'leg_contacts',
    'rest_height_m',
    'single_support',
]

FloatArray = NDArray[np.float64]
GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class LegGeometry:
    """Robot description for the geometric contact model (EduBot defaults, SI units).

    Attributes
    ----------
    hip_x_m : tuple of 3 float
        Hip positions along the body's longitudinal axis from the COM [m]: front, middle, rear.
    hip_z_m : float
        Hip height above the COM along the body's vertical axis [m].
    leg_radius_m : float
        Arc radius ``R`` of the half-circle leg [m] (hip-to-toe chord ``2 R``).
    hip_zero_rad : float
        Leg angle from the body's downward axis at zero hip angle [rad]: shaft angle from the
        true vertical = hip angle + pitch + ``hip_zero_rad``.
    """

    hip_x_m: tuple[float, float, float] = (0.20, 0.0, -0.20)
    hip_z_m: float = 0.0
    leg_radius_m: float = 0.073
    hip_zero_rad: float = -0.21

    @classmethod
    def from_params(cls, params: Any) -> LegGeometry:
        """From an object with EduBot parameter names (``hip_x_m``, ``hip_z_m``,
        ``leg_rest_length_m`` = 2 R, ``hip_zero_rad``), e.g. the simulator's ``EdubotParams``."""
        return cls(hip_x_m=tuple(float(v) for v in params.hip_x_m),  # type: ignore[arg-type]
                   hip_z_m=float(params.hip_z_m),
                   leg_radius_m=0.5 * float(params.leg_rest_length_m),
                   hip_zero_rad=float(params.hip_zero_rad))

    def hip_x_of(self, leg: str) -> float:
        """Hip x of leg ``'<side><1|2|3>'`` (1 front, 2 middle, 3 rear) [m]."""
        try:
            i = int(leg[1]) - 1
            return float(self.hip_x_m[i])
        except (IndexError, ValueError) as err:
            raise SlipDataError(f"leg name {leg!r}: expected '<L|R><1|2|3>'") from err


def rest_height_m(psi_rad: ArrayLike, radius_m: float) -> FloatArray:
    """Rest-shape height of the leg's lowest point below the hip [m], same shape as ``psi``.

    ``2 R cos(psi)`` (toe contact, ``psi < 0``), ``R (1 + cos psi)`` (rolling,
    ``0 <= psi < pi``); ``psi`` is wrapped to ``[-pi, pi)``; a leg pointing up gives -1 m
    (never in contact).
    """
    psi = np.asarray(psi_rad, dtype=float)
    w = psi - 2 * np.pi * np.floor(psi / (2 * np.pi) + 0.5)
    c = np.cos(w)
    roll = (w >= 0) & (w < np.pi)
    return np.where(roll, radius_m * (1 + c), np.where(c > 0, 2 * radius_m * c, -1.0))


def body_pitch_rad(world_rotation: ArrayLike, quat_xyzw: ArrayLike) -> FloatArray:
    """Body pitch (REP-103, nose down positive) in a world frame, shape (n,).

    ``world_rotation`` (3, 3): rows are the world axes in the mocap frame
    (:class:`.preprocess.WorldFrame`); ``quat_xyzw`` (n, 4) body orientations in the mocap frame.
    """
    q = np.atleast_2d(np.asarray(quat_xyzw, dtype=float))
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    bx = np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)])
    bw = bx @ np.asarray(world_rotation, dtype=float).T
    return np.arctan2(-bw[:, 2], bw[:, 0])


@dataclass(frozen=True)
class GeometryFit:
    """Result of :func:`fit_ground_offset`.

    ``offset_s``: subtract from mocap stamps; ``ground_m``: ground height in the world frame the
    heights were given in [m]; ``rms_m``: residual RMS of the body height [m]; ``windows``:
    windows used; ``damping_ratio_s``: fitted c / mean k [s].
    """

    offset_s: float
    ground_m: float
    rms_m: float
    windows: int
    damping_ratio_s: float


class _Body:
    """Splines of mocap height and pitch (mocap clock) and of hip angles (proprio clock)."""

    def __init__(self, geometry: LegGeometry, joint_names: tuple[str, ...], joint_t_s: ArrayLike,
                 joint_position: ArrayLike, joint_velocity: ArrayLike, mocap_t_s: ArrayLike,
                 height_m: ArrayLike, pitch_rad: ArrayLike) -> None:
        self.geo = geometry
        tj = np.asarray(joint_t_s, dtype=float)
        q = np.asarray(joint_position, dtype=float)
        v = np.asarray(joint_velocity, dtype=float)
        self.legs = [n[:-4] for n in joint_names if n.endswith('_hip')]
        cols = [joint_names.index(f'{leg}_hip') for leg in self.legs]
        if not cols:
            raise SlipDataError(f'no <leg>_hip joints in {joint_names}')
        ok = np.isfinite(tj) & np.all(np.isfinite(q[:, cols]), axis=1)
        ok &= np.all(np.isfinite(v[:, cols]), axis=1)
        tj, q, v = tj[ok], q[ok][:, cols], v[ok][:, cols]
        if tj.size < 10:
            raise SlipDataError(f'geometry needs >= 10 finite hip samples, got {tj.size}')
        o = np.argsort(tj)
        keep = np.concatenate([[True], np.diff(tj[o]) > 0])
        o = o[keep]
        self.t_j = tj[o]
        self.phi = CubicHermiteSpline(tj[o], q[o], v[o])
        tm = np.asarray(mocap_t_s, dtype=float)
        z = np.asarray(height_m, dtype=float)
        b = np.asarray(pitch_rad, dtype=float)
        ok = np.isfinite(tm) & np.isfinite(z) & np.isfinite(b)
        tm, z, b = tm[ok], z[ok], b[ok]
        o = np.argsort(tm)
        keep = np.concatenate([[True], np.diff(tm[o]) > 0])
        o = o[keep]
        if o.size < 20:
            raise SlipDataError(f'geometry needs >= 20 mocap samples, got {o.size}')
        self.tm, self.z, self.b = tm[o], z[o], b[o]
        self.zs = CubicSpline(self.tm, self.z)
        self.bs = CubicSpline(self.tm, self.b)
        self.hx = np.array([geometry.hip_x_of(leg) for leg in self.legs])

    def gaps(self, tf: FloatArray, offset_s: float, ground_m: float) -> FloatArray:
        """(n, L) hip height minus rest height [m] at proprio times ``tf``."""
        z = self.zs(tf + offset_s) - ground_m
        b = self.bs(tf + offset_s)
        hip = (z[:, None] - self.hx[None, :] * np.sin(b)[:, None]
               + self.geo.hip_z_m * np.cos(b)[:, None])
        psi = self.phi(tf) + b[:, None] + self.geo.hip_zero_rad
        return hip - rest_height_m(psi, self.geo.leg_radius_m)


def _windows(tm: FloatArray, window_s: float) -> list[NDArray[np.bool_]]:
    """Masks of consecutive windows of ``window_s`` over gap-free mocap segments."""
    dt = float(np.median(np.diff(tm)))
    breaks = np.flatnonzero(np.diff(tm) > 2.5 * dt)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks + 1, [tm.size]])
    out = []
    for a, b in zip(starts, ends):
        if tm[b - 1] - tm[a] < window_s:
            continue
        edges = np.arange(tm[a], tm[b - 1] + 1e-9, window_s)
        for w0, w1 in zip(edges[:-1], edges[1:]):
            k = np.zeros(tm.size, dtype=bool)
            k[a:b] = (tm[a:b] >= w0) & (tm[a:b] < w1)
            if k.sum() >= 8:
                out.append(k)
    return out


def _cost(body: _Body, masks: list[NDArray[np.bool_]], t_lo: float, t_hi: float,
          offset_s: float, ground_m: float, *, step_s: float = 1e-3,
          full: bool = False) -> Any:
    """Mean squared residual of the per-window dynamics fit for one (offset, ground)."""
    tf = np.arange(t_lo - offset_s, t_hi - offset_s + step_s, step_s)
    pen = np.maximum(-body.gaps(tf, offset_s, ground_m), 0.0).sum(axis=1)
    i1 = np.concatenate([[0.0], np.cumsum(0.5 * (pen[1:] + pen[:-1])) * step_s])
    i2 = np.concatenate([[0.0], np.cumsum(0.5 * (i1[1:] + i1[:-1])) * step_s])
    ts = body.tm - offset_s
    y = body.z - ground_m + 0.5 * GRAVITY_M_S2 * (ts - ts[0]) ** 2
    a2 = np.interp(ts, tf, i2)
    a1 = np.interp(ts, tf, i1)
    n_w = len(masks)
    used = np.zeros(ts.size, dtype=bool)
    a = np.zeros((ts.size, 3 * n_w + 1))
    for w, k in enumerate(masks):
        used |= k
        a[k, 3 * w] = 1.0
        a[k, 3 * w + 1] = ts[k] - ts[k][0]
        a[k, 3 * w + 2] = a2[k]
    a[:, -1] = a1
    a, y = a[used], y[used]
    scale = np.maximum(np.abs(a).max(axis=0), 1e-300)
    coef, *_ = np.linalg.lstsq(a / scale, y, rcond=None)
    coef = coef / scale
    r = y - a @ coef
    mse = float(r @ r) / max(int(used.sum()), 1)
    if full:
        k_mean = float(np.mean(coef[2::3][:n_w]))
        return mse, int(used.sum()), (float(coef[-1]) / k_mean if k_mean > 0 else math.nan)
    return mse


def fit_ground_offset(geometry: LegGeometry, joint_names: tuple[str, ...], joint_t_s: ArrayLike,
                      joint_position: ArrayLike, joint_velocity: ArrayLike,
                      mocap_t_s: ArrayLike, height_m: ArrayLike, pitch_rad: ArrayLike, *,
                      initial_offset_s: float = 0.0, offset_range_s: float = 0.015,
                      ground_range_m: tuple[float, float] = (-0.05, 0.05),
                      window_s: float = 0.3, min_windows: int = 3,
                      fix_offset: bool = False) -> GeometryFit:
    """Stream offset and ground height from the body's vertical dynamics (module docs).

    Parameters
    ----------
    geometry : LegGeometry
    joint_names : tuple of str
        Joint names; ``<leg>_hip`` columns are used.
    joint_t_s : array_like, shape (n,)
        Proprioception stamps [s].
    joint_position, joint_velocity : array_like, shape (n, J)
        Hip angles [rad] (unwrapped) and speeds [rad/s].
    mocap_t_s : array_like, shape (m,)
        Raw mocap stamps [s] (mocap clock).
    height_m, pitch_rad : array_like, shape (m,)
        COM height in a world frame whose ground height is unknown [m]; pitch [rad].
    initial_offset_s : float
        Centre of the offset search [s] (e.g. the joint or contact estimate).
    offset_range_s : float
        Half-width of the coarse offset grid [s].
    ground_range_m : (float, float)
        Coarse ground-height grid bounds [m].
    fix_offset : bool
        Keep ``initial_offset_s`` (a known offset) and fit the ground height only.

    Returns
    -------
    GeometryFit
    """
    body = _Body(geometry, tuple(joint_names), joint_t_s, joint_position, joint_velocity,
                 mocap_t_s, height_m, pitch_rad)
    masks = _windows(body.tm, window_s)
    if len(masks) < min_windows:
        raise SlipDataError(f'geometry fit: {len(masks)} gap-free mocap windows of {window_s} s, '
                            f'need >= {min_windows}')
    lo_j, hi_j = body.t_j[0], body.t_j[-1]
    t_lo = max(body.tm[0], lo_j + initial_offset_s + offset_range_s + 0.02)
    t_hi = min(body.tm[-1], hi_j + initial_offset_s - offset_range_s - 0.02)
    keep = (body.tm >= t_lo) & (body.tm <= t_hi)
    masks = [k & keep for k in masks]
    masks = [k for k in masks if k.sum() >= 8]
    if len(masks) < min_windows:
        raise SlipDataError(f'geometry fit: {len(masks)} mocap windows overlap the hip '
                            f'angles, need >= {min_windows}')

    def f(d: float, g: float) -> float:
        return _cost(body, masks, t_lo, t_hi, d, g)

    # coarse: ground on 2 mm, offset on 2.5 ms steps; then Nelder-Mead from the best
    d_grid = initial_offset_s + np.arange(-offset_range_s, offset_range_s + 1e-9, 2.5e-3)
    g_grid = np.arange(ground_range_m[0], ground_range_m[1] + 1e-9, 2e-3)
    g_best = min(g_grid, key=lambda g: f(initial_offset_s, g))
    if fix_offset:
        r1 = minimize_scalar(lambda g: f(initial_offset_s, g), method='bounded',
                             bounds=(g_best - 2.5e-3, g_best + 2.5e-3),
                             options={'xatol': 1e-5})
        d, g = float(initial_offset_s), float(r1.x)
        mse, _, ratio = _cost(body, masks, t_lo, t_hi, d, g, full=True)
        return GeometryFit(offset_s=d, ground_m=g, rms_m=math.sqrt(mse), windows=len(masks),
                           damping_ratio_s=ratio)
    d_best = min(d_grid, key=lambda d: f(d, g_best))
    g_best = min(g_best + np.arange(-4e-3, 4.01e-3, 1e-3), key=lambda g: f(d_best, g))
    s_d, s_g = 1e3, 1e3  # ms and mm for the simplex
    res = minimize(lambda v: f(v[0] / s_d, v[1] / s_g) * 1e8, [d_best * s_d, g_best * s_g],
                   method='Nelder-Mead',
                   options={'xatol': 0.02, 'fatol': 1e-6,
                            'initial_simplex': [[d_best * s_d, g_best * s_g],
                                                [d_best * s_d + 2.0, g_best * s_g],
                                                [d_best * s_d, g_best * s_g + 2.0]]})
    d, g = float(res.x[0] / s_d), float(res.x[1] / s_g)
    mse, n, ratio = _cost(body, masks, t_lo, t_hi, d, g, full=True)
    return GeometryFit(offset_s=d, ground_m=g, rms_m=math.sqrt(mse), windows=len(masks),
                       damping_ratio_s=ratio)


def leg_contacts(geometry: LegGeometry, joint_names: tuple[str, ...], joint_t_s: ArrayLike,
                 joint_position: ArrayLike, joint_velocity: ArrayLike, mocap_t_s: ArrayLike,
                 height_m: ArrayLike, pitch_rad: ArrayLike, *, offset_s: float,
                 ground_m: float, step_s: float = 5e-4) -> dict[str, FloatArray]:
    """Per-leg contact intervals where the hip is below the leg's rest height, (k, 2) [s].

    Times are in the proprioception clock, over the span the mocap (shifted by ``offset_s``)
    covers; edges are the interpolated zero crossings of hip height minus rest height (a
    contact cut by the span's ends is dropped). Arguments as :func:`fit_ground_offset`.
    """
    body = _Body(geometry, tuple(joint_names), joint_t_s, joint_position, joint_velocity,
                 mocap_t_s, height_m, pitch_rad)
    t0 = max(body.tm[0] - offset_s, body.t_j[0])
    t1 = min(body.tm[-1] - offset_s, body.t_j[-1])
    tf = np.arange(t0, t1, step_s)
    # no contact across a mocap gap (the spline there is not data)
    dt = float(np.median(np.diff(body.tm)))
    gi = np.flatnonzero(np.diff(body.tm) > 2.5 * dt)
    in_gap = np.zeros(tf.size, dtype=bool)
    for i in gi:
        in_gap |= (tf + offset_s > body.tm[i]) & (tf + offset_s < body.tm[i + 1])
    gaps = body.gaps(tf, offset_s, ground_m)
    out: dict[str, FloatArray] = {}
    for j, leg in enumerate(body.legs):
        s = gaps[:, j]
        c = np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))
        tc = tf[c] + step_s * s[c] / (s[c] - s[c + 1])
        down = s[c] > 0
        iv = []
        k = 0
        while k < c.size:
            if down[k] and k + 1 < c.size and not down[k + 1]:
                a, b = c[k], c[k + 1]
                if not np.any(in_gap[a:b + 2]):
                    iv.append((tc[k], tc[k + 1]))
                k += 2
            else:
                k += 1
        out[leg] = np.array(iv, dtype=float).reshape(-1, 2)
    return out


def _union(iv: list[FloatArray]) -> FloatArray:
    x = np.concatenate([np.asarray(v).reshape(-1, 2) for v in iv]) if iv else np.zeros((0, 2))
    if x.size == 0:
        return x
    x = x[np.argsort(x[:, 0])]
    out = [list(x[0])]
    for a, b in x[1:]:
        if a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return np.array(out, dtype=float)


def single_support(contacts: dict[str, FloatArray], tripods: dict[str, tuple[str, ...]]
                   ) -> dict[str, FloatArray]:
    """Per tripod, the intervals where any of its legs is in contact and no leg of the others.

    Returns ``{tripod: (k, 2)}`` [s], the longest piece of each tripod contact interval.
    """
    on = {tp: _union([contacts[leg] for leg in legs if leg in contacts])
          for tp, legs in tripods.items()}
    out: dict[str, FloatArray] = {}
    for tp, iv in on.items():
        others = _union([v for k, v in on.items() if k != tp])
        pieces = []
        for a, b in iv:
            segs = [(a, b)]
            for c, d in others:
                nxt = []
                for s0, s1 in segs:
                    if d <= s0 or c >= s1:
                        nxt.append((s0, s1))
                        continue
                    if c > s0:
                        nxt.append((s0, c))
                    if d < s1:
                        nxt.append((d, s1))
                segs = nxt
            if segs:
                pieces.append(max(segs, key=lambda x: x[1] - x[0]))
        out[tp] = np.array(pieces, dtype=float).reshape(-1, 2)
    return out
