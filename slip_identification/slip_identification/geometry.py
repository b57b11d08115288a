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
(:class:`LegGeometry`, the robot description). A leg that has lifted off lands again only once
its lowest point has cleared the ground by ``LegGeometry.rearm_clearance_m`` (2 mm): a leaning
leg can spring off while its rest shape still reaches below the ground.

Ground height and stream offset (:func:`fit_ground_offset`): the ground is invisible to the
motion capture, whose clock is offset from the proprioception clock. Every leg's penetration
``p_j(t) = max(0, rest_j(t) - hip height_j(t))`` follows from the hip angles and the mocap body
(shifted by the offset ``d``, lowered by the ground height ``g``); the vertical dynamics
``m (z'' + g) = k_w sum_j max(0, p_j + tau p_j')`` (a leg cannot pull; ``tau`` the leg's
damping over stiffness; a stiffness per window), integrated twice plus a free height and
velocity per window, are linear in their coefficients for given ``(d, g)``, which minimise the
residual (coarse grid, outlier windows dropped, then Nelder-Mead). Windows run between the
middles of flight phases when the gait has them, else 0.1 s (over longer windows force-model
errors, integrated twice, dominate). Contact timing in the fast phase determines ``d``; ``g``
is fixed by where contacts begin and end. A fitted ``tau`` makes ``d`` less certain.

This equation-error fit has the noisy measured heights in its regressors, so its ground is
biased (errors in variables). The OUTPUT-ERROR refinement (``refine='output'``, the default)
integrates ``h'' = k sum_j max(0, p_j + tau p_j') - g0`` per window on the 1 kHz grid (Heun, all
windows at once) with the penetrations from the SIMULATED height ``h``, and fits offset, ground,
tilt and each window's stiffness, start height and velocity to the measured height
(Levenberg-Marquardt from the equation-error fit), so height noise enters the target only.
Without flight phases its windows are the 0.1 s windows joined in pairs (``output_window_s``,
0.2 s; 0.1 s leaves about 12 samples for three free parameters). Windows the simulation cannot
follow (RMS above twice the median window's) are dropped once.

Ground slope (``tilt_rad``): a world frame levelled on the COM path is tilted by the path's own
slope. Without flight phases, when the steady part (:func:`.steady.steady_start_s`) spans 1.5
periods and 0.1 m, the slope comes from whole strides (:func:`stride_slope_rad`,
``tilt_from_strides``: one-period mean heights against their mean x); the fitted slope is kept
instead only when it lowers the residual by more than a parameter's price. With flight phases
the ballistic windows pin the slope and it is fitted.

Rigid body's pitch zero (``pitch_offset_rad``, :class:`GeometryFit`): a rigid body's up axis
need not be normal to the hip line; the hip heights then carry ``hip_x * sin(zero)``. The zero
is tried free beside the prior (default 0): offset searched from where the median pitch is
level, a 1-degree scan, then both fits with the zero (and slope) free, with a second start
from a level ground when the median pitch is over half a degree from the prior. The better free
fit is kept when it beats the Bayesian information criterion's price of a parameter and lies
0.25 deg or more and three standard errors from the prior. Limitation: its Jacobian standard
error is optimistic.

Edges (:func:`leg_contacts`): in steady state a leg lands at the same phase every stride, so
with ``pool_steady`` each leg's steady edges of one kind are shrunk toward their median phase
(:func:`_pool_edges`), by their own variance (height error over the gap's median rate) against
the stride-to-stride spread. The pitch is smoothed by a local quadratic over
:data:`PITCH_SMOOTHING_S` when its noise (:func:`white_noise_std`) is above
:data:`PITCH_NOISE_MIN_RAD`; the ground and offset fit takes the raw pitch.

Limitations: slow crossings (pace and walk edges) turn 0.1-0.3 mm of height, ground or pitch
error into several ms; the penetrations use the measured pitch; the legs' bending compliance
is not modelled.

Core module: numpy/scipy only (does not import the simulator: pass its parameters to
:meth:`LegGeometry.from_params`).
Measurements and design history: docs/slip_geometry_notes.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import CubicHermiteSpline, CubicSpline, PPoly
from scipy.optimize import least_squares, minimize, minimize_scalar
from scipy.signal import savgol_filter

from hexapod_common.series import robust_sigma

from ._geometry_kernels import HAVE_NUMBA, cost_mse, leg_gaps, simulate_windows
from .errors import SlipDataError
from .preprocess import max_mocap_gap_s
from .stance import longest_free_segment
from .steady import steady_start_s, white_noise_std

__all__ = [
    'GeometryFit',
    'LegGeometry',
    'body_pitch_rad',
    'auto_pitch_smoothing',
    'white_noise_std',
    'FIT_MODELS',
    'fit_ground_offset',
    'prefer_fit',
    'leg_contacts',
    'offset_ground_grid',
    'rest_height_m',
    'single_support',
    'stride_slope_rad',
    'unwrap_with_speed',
]

FloatArray = NDArray[np.float64]
GRAVITY_M_S2 = 9.81
#: run the output-error refinement's simulation compiled when numba is installed (the numpy
#: loop otherwise; the two agree to rounding, test_slip_geometry_kernel.py)
COMPILED_SIMULATION = True
#: evaluate the equation-error cost's scalar path (the offset and ground searches) compiled
#: when numba is installed (the numpy code otherwise; the two agree to rounding,
#: test_slip_geometry_kernel.py)
COMPILED_COST = True
#: span of the pitch smoother [s] (:func:`leg_contacts`' default): a local quadratic over the
#: odd number of mocap samples nearest to it (9 at 120 Hz; module docs), used when the pitch's
#: noise is above :data:`PITCH_NOISE_MIN_RAD`
PITCH_SMOOTHING_S = 0.07
#: pitch noise [rad] (from fourth differences) above which :func:`leg_contacts` smooths the
#: pitch by default: simulated motion capture (0.2 mm markers 0.25 m apart) reads 0.67 mrad,
#: the simulator's noise-free pitch 0.01-0.15 mrad at 100-120 Hz
PITCH_NOISE_MIN_RAD = 3e-4
#: half-width of the scan for the rigid body's pitch zero against the hip line [rad], around
#: the zero that levels the median pitch (itself within PITCH_OFFSET_CENTRE_RAD of the prior;
#: rigid bodies 10 deg off are found, module docs)
PITCH_OFFSET_RANGE_RAD = math.radians(4.0)
PITCH_OFFSET_CENTRE_RAD = math.radians(12.0)
#: the legs' stiffness from the body-height fit (GeometryFit.stiffness_per_kg times the mass)
#: further than this fraction from LegGeometry.damping_stiffness_n_m refutes the default
#: damping time (EduBot simulated runs, four gaits x 3 seeds: -6.6 % to +2.2 %; a review
#: of the change read -8.4 % on pace seed 3, 3480 N/m)
DAMPING_STIFFNESS_TOLERANCE = 0.25
#: a fitted pitch zero closer than this to the prior is not kept [rad]: on simulated runs with
#: a known zero the free fit scatters by 0.1-0.2 deg (start-up transients), and kept there it
#: cost a pace run every edge within 5 ms
PITCH_OFFSET_MIN_RAD = math.radians(0.25)


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
    leg_damping_time_s : float or None
        The leg's radial damping over its radial stiffness [s] (e.g. from a drop test of one
        leg), or None when unknown: :func:`fit_ground_offset` then fits it, at the price of
        a less certain offset (the damper advances the force like a clock shift).
    rearm_clearance_m : float
        Clearance [m] a leg's lowest point must reach above the ground after a lift-off
        before a new contact counts (:func:`leg_contacts`): contact hysteresis.
    damping_assumed : bool
        ``leg_damping_time_s`` is a default, not this robot's (another robot's legs given
        without a damping time): the pipeline checks it against undamped legs and keeps the
        better fit of the body height.
    damping_stiffness_n_m : float or None
        The leg stiffness [N/m] that the default damping time belongs to (EduBot's 3800 N/m:
        12.9 N s/m over it), or None when the damping time is this robot's (given, or from
        :meth:`from_params`). With it the pipeline compares the legs' stiffness that the
        body-height fit finds: more than :data:`DAMPING_STIFFNESS_TOLERANCE` away, the
        default damping time is not this robot's either and is fitted (an outside review:
        legs of 2000 N/m kept 3.39 ms for 6.45, the offset 10 ms and every edge 7 ms off).
    """

    hip_x_m: tuple[float, float, float] = (0.20, 0.0, -0.20)
    hip_z_m: float = 0.0
    leg_radius_m: float = 0.0525
    hip_zero_rad: float = 0.0
    leg_damping_time_s: float | None = 12.9 / 3800.0
    rearm_clearance_m: float = 0.002
    damping_assumed: bool = False
    damping_stiffness_n_m: float | None = 3800.0

    @classmethod
    def from_params(cls, params: Any, *, with_damping: bool = True) -> LegGeometry:
        """From an object with EduBot parameter names (``hip_x_m``, ``hip_z_m``,
        ``leg_rest_length_m`` = 2 R, ``hip_zero_rad``; for the damping time
        ``leg_radial_damping_n_s_m`` / ``leg_stiffness_n_m``), e.g. the simulator's
        ``EdubotParams``. ``with_damping=False`` leaves the damping time unknown."""
        tau = None
        if with_damping and hasattr(params, 'leg_radial_damping_n_s_m') and \
                float(getattr(params, 'leg_stiffness_n_m', 0.0)) > 0:
            tau = float(params.leg_radial_damping_n_s_m) / float(params.leg_stiffness_n_m)
        return cls(hip_x_m=tuple(float(v) for v in params.hip_x_m),  # type: ignore[arg-type]
                   hip_z_m=float(params.hip_z_m),
                   leg_radius_m=0.5 * float(params.leg_rest_length_m),
                   hip_zero_rad=float(params.hip_zero_rad), leg_damping_time_s=tau,
                   damping_stiffness_n_m=None)

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
    (:class:`.preprocess.WorldFrame`, x along the run); ``quat_xyzw`` (n, 4) body orientations
    in the mocap frame.

    The pitch is the tilt of the body's up axis (its z) towards the run's direction,
    ``atan2(z_b . x_w, z_b . z_w)``: it does not depend on where the rigid body's x axis points
    in the horizontal plane. A motion-capture rigid body is often defined with its axes as the
    robot stood when it was created (OptiTrack), so its x need not be the robot's forward; the
    pitch from the body x axis made such runs' single supports meaningless (an EduBot run with
    the body frame turned 90 deg about z: 213 stances too short, none fitted). For a body
    frame with x forward the two agree (a rotation about the lateral axis moves both alike).
    """
    q = np.atleast_2d(np.asarray(quat_xyzw, dtype=float))
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    bz = np.column_stack([2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)])
    bw = bz @ np.asarray(world_rotation, dtype=float).T
    return np.arctan2(bw[:, 0], bw[:, 2])


@dataclass(frozen=True)
class GeometryFit:
    """Result of :func:`fit_ground_offset`.

    ``offset_s``: subtract from mocap stamps; ``ground_m``: ground height in the world frame the
    heights were given in [m]; ``rms_m``: residual RMS of the body height [m]; ``windows``:
    windows used; ``damping_ratio_s``: fitted c / mean k [s]; ``height_t_s`` (mocap clock),
    ``height_m``: the fitted body height on a 1 ms grid (same frame as the input heights, NaN
    outside the windows, above the tilted ground), the noise-free height :func:`leg_contacts`
    can use; ``dropped_windows``: windows left out as outliers; ``tilt_rad``: the ground's
    slope along +x in the given frame (fitted when x is given), the heights above it are
    ``z - tilt_rad (x - tilt_x0_m)`` and the pitch from it ``pitch + tilt_rad +
    pitch_offset_rad``; ``pitch_offset_rad``: the motion-capture rigid body's pitch zero
    against the hip line (its pitch while the hips are level), the prior or, when
    ``pitch_offset_fitted``, fitted (standard error ``pitch_offset_se_rad``, from the
    Jacobian: autocorrelated residuals make it optimistic); ``unrefined``: the output-error
    refinement was asked for (``refine='output'``) and failed, so ``rms_m`` is the
    equation-error fit's, over shorter windows with three free parameters each (0.1 s without
    flight phases: about 12 samples), below a refined fit's at the same offset and not
    comparable with it (a simulated walk half a stride off: 0.164 against 0.206 mm refined);
    ``equation_rms_m``: the equation-error fit's residual RMS [m] (``rms_m`` without the
    refinement), the residual every fit has: :func:`prefer_fit` compares a refined fit with an
    unrefined one by it.
"""

    offset_s: float
    ground_m: float
    rms_m: float
    windows: int
    damping_ratio_s: float
    height_t_s: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0), repr=False)
    height_m: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0), repr=False)
    dropped_windows: int = 0
    tilt_rad: float = 0.0
    tilt_x0_m: float = 0.0
    pitch_offset_rad: float = 0.0
    pitch_offset_fitted: bool = False
    pitch_offset_se_rad: float = math.nan
    tilt_source: str = 'fitted'
    stiffness_per_kg: float = math.nan
    samples: int = 0
    flight: bool = False
    unrefined: bool = False
    equation_rms_m: float = math.nan


#: the equation-error residual by which a fit whose output-error refinement failed must beat
#: a refined one (:func:`prefer_fit`): the failure is evidence against it (the simulated
#: dynamics do not follow the body height near it). A mocap origin 12 cm above the floor
#: (simulated jogging, seed 3) gave a first fit whose legs never touch the ground (ground
#: 133 mm off, offset 57 ms off; ballistic parabolas fit its windows) 1.2 % below the
#: refined fit at the true ground on this residual
UNREFINED_MARGIN = 0.05


def prefer_fit(alt: Any, base: Any, factor: float = 1.0) -> bool:
    """Whether the body-height fit ``alt`` is to be preferred to ``base``: its residual below
    ``factor`` times ``base``'s (``factor`` < 1: clearly better; > 1: about as good).

    ``alt``, ``base``: :class:`GeometryFit` (or anything with ``rms_m``, ``unrefined`` and
    ``equation_rms_m``). Two fits alike (both refined by the output-error fit, or neither)
    compare ``rms_m``. A refined fit and one whose refinement failed (``unrefined``) compare
    the residual both have, the equation-error fit's (``equation_rms_m``), the unrefined one's
    counted :data:`UNREFINED_MARGIN` higher. An unrefined ``rms_m`` is the equation-error
    fit's, over shorter windows with free parameters of their own, 20-23 % below a refined
    fit's at the same offset on gaits without flight (4-5 % with flight; simulated EduBot, four
    gaits x 5 seeds), so that comparing ``rms_m`` let unrefined fits win (a pace run's offset
    315 ms off, another's 84 ms). Without ``equation_rms_m`` the refined fit is preferred.
    """
    if bool(alt.unrefined) == bool(base.unrefined):
        return bool(alt.rms_m < factor * base.rms_m)
    a, b = float(alt.equation_rms_m), float(base.equation_rms_m)
    if not (math.isfinite(a) and math.isfinite(b)):
        return bool(base.unrefined)
    if alt.unrefined:
        a *= 1.0 + UNREFINED_MARGIN
    else:
        b *= 1.0 + UNREFINED_MARGIN
    return a < factor * b


#: the ground's slope from whole strides needs this many gait periods of steady state
STRIDE_SLOPE_MIN_PERIODS = 1.5
#: ... and this much travel along x within them [m]
STRIDE_SLOPE_MIN_TRAVEL_M = 0.1


def stride_slope_rad(t_s: ArrayLike, height_m: ArrayLike, x_m: ArrayLike, pitch_rad: ArrayLike,
                     period_s: float, *, step_s: float = 0.01) -> float | None:
    """The ground's slope along x from whole strides [rad], or None.

    In steady state the body's mean height over one gait period is the same from stride to
    stride, so on a sloping ground (or in a frame whose x axis is not level) the mean height
    over a period, against the mean x over it, rises with the ground's slope. The means over
    every window of one period starting every ``step_s`` in the steady part
    (:func:`.steady.steady_start_s`, from the pitch) are regressed on each other; a moving
    average over exactly one period removes the periodic motion whatever its phase. None when
    the steady part is shorter than :data:`STRIDE_SLOPE_MIN_PERIODS` periods, the body travels
    less than :data:`STRIDE_SLOPE_MIN_TRAVEL_M` in it, or a motion-capture gap (over
    :func:`.preprocess.max_mocap_gap_s`) falls in every window.
    """
    t = np.asarray(t_s, dtype=float)
    z = np.asarray(height_m, dtype=float)
    x = np.asarray(x_m, dtype=float)
    b = np.asarray(pitch_rad, dtype=float)
    ok = np.isfinite(t) & np.isfinite(z) & np.isfinite(x) & np.isfinite(b)
    t, z, x, b = t[ok], z[ok], x[ok], b[ok]
    if not (math.isfinite(period_s) and period_s > 0) or t.size < 20:
        return None
    t0 = steady_start_s(t, b, period_s)
    if not math.isfinite(t0) or t[-1] - t0 < STRIDE_SLOPE_MIN_PERIODS * period_s:
        return None
    if float(np.ptp(x[t >= t0])) < STRIDE_SLOPE_MIN_TRAVEL_M:
        return None
    # window means of the linear interpolant: differences of its running integral
    dt = float(np.median(np.diff(t)))
    jump = np.diff(t) > max_mocap_gap_s(dt)
    a = np.arange(t0, t[-1] - period_s + 1e-9, step_s)
    crossed = (t[1:][jump][None, :] > a[:, None]) & (t[:-1][jump][None, :] < a[:, None] + period_s)
    a = a[~np.any(crossed, axis=1)]
    if a.size < 2:
        return None
    means = [np.diff(np.interp([a, a + period_s], t, cumulative_trapezoid(v, t, initial=0.0)),
                     axis=0)[0] / period_s for v in (x, z)]
    if not np.ptp(means[0]) > 0:
        return None
    return float(np.polyfit(means[0], means[1], 1)[0])


def unwrap_with_speed(t_s: FloatArray, angle_rad: FloatArray, speed_rad_s: FloatArray
                      ) -> FloatArray:
    """Angles (n, m) with wraps removed: each step's whole turns taken off where the measured
    step and the speeds' trapezoid over it differ by more than half a turn (a driver that
    wraps to (-pi, pi] or [0, 2 pi); the speeds carry the turns across a sampling gap too,
    where np.unwrap would not). Continuous angles come back unchanged."""
    if angle_rad.shape[0] < 2:
        return angle_rad
    dq = np.diff(angle_rad, axis=0)
    pred = 0.5 * (speed_rad_s[1:] + speed_rad_s[:-1]) * np.diff(t_s)[:, None]
    turns = np.round((dq - pred) / (2 * math.pi))
    if not np.any(turns):
        return angle_rad
    return angle_rad - 2 * math.pi * np.concatenate(
        [np.zeros((1, angle_rad.shape[1])), np.cumsum(turns, axis=0)])


class _Body:
    """Splines of mocap height and pitch (mocap clock) and of hip angles (proprio clock)."""

    def __init__(self, geometry: LegGeometry, joint_names: tuple[str, ...], joint_t_s: ArrayLike,
                 joint_position: ArrayLike, joint_velocity: ArrayLike, mocap_t_s: ArrayLike,
                 height_m: ArrayLike, pitch_rad: ArrayLike, x_m: ArrayLike | None = None,
                 pitch_smoothing: int | None = 0) -> None:
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
        self.phi = CubicHermiteSpline(tj[o], unwrap_with_speed(tj[o], q[o], v[o]), v[o])
        tm = np.asarray(mocap_t_s, dtype=float)
        z = np.asarray(height_m, dtype=float)
        b = np.asarray(pitch_rad, dtype=float)
        x = np.zeros_like(z) if x_m is None else np.asarray(x_m, dtype=float)
        if x.shape != z.shape:
            raise SlipDataError(f'x_m has shape {x.shape}, expected that of height_m {z.shape}')
        ok = np.isfinite(tm) & np.isfinite(z) & np.isfinite(b) & np.isfinite(x)
        tm, z, b, x = tm[ok], z[ok], b[ok], x[ok]
        o = np.argsort(tm)
        keep = np.concatenate([[True], np.diff(tm[o]) > 0])
        o = o[keep]
        if o.size < 20:
            raise SlipDataError(f'geometry needs >= 20 mocap samples, got {o.size}')
        self.tm, self.z_raw, self.b_raw, self.x = tm[o], z[o], b[o], x[o]
        if pitch_smoothing is None:
            pitch_smoothing = auto_pitch_smoothing(self.tm, self.b_raw)
        if pitch_smoothing > 2:
            self.b_raw = _smooth_segments(self.tm, self.b_raw, pitch_smoothing)
        self.x0 = float(np.mean(self.x))
        # the splines are linear in their data: the tilted height's and the shifted pitch's
        # are combinations of these three (no spline built per trial tilt)
        self._zc = CubicSpline(self.tm, self.z_raw).c
        self._xc = CubicSpline(self.tm, self.x).c
        self._bc = CubicSpline(self.tm, self.b_raw).c
        self.tilt = math.nan
        self.pitch0 = 0.0
        self.set_tilt(0.0)
        self._phi_key: Any = None
        self._h_version = 0
        self._gap_tf: Any = None
        self._gap_key: Any = None
        self._gap0 = np.zeros((0, len(self.legs)))
        self._h_t = np.zeros(0)
        self._h_z = np.zeros(0)
        self._phi_cache = np.zeros((0, len(self.legs)))
        self.hx = np.array([geometry.hip_x_of(leg) for leg in self.legs])
        # the fits' last list of window masks and its indices (_window_index)
        self.window_index: tuple[Any, Any] = (None, None)

    def set_tilt(self, tilt_rad: float, pitch_offset_rad: float | None = None) -> None:
        """Ground rising along +x by ``tilt_rad`` in the given frame: heights above a level
        ground are ``z - tilt (x - x0)``, pitch from the ground ``pitch + tilt + pitch0``
        (``pitch_offset_rad``, kept when None: the rigid body's pitch zero against the hip
        line, :class:`GeometryFit`)."""
        p0 = self.pitch0 if pitch_offset_rad is None else float(pitch_offset_rad)
        if tilt_rad == self.tilt and p0 == self.pitch0:
            return
        if tilt_rad != self.tilt:
            self.tilt = float(tilt_rad)
            self.z = self.z_raw - self.tilt * (self.x - self.x0)
            zc = self._zc - self.tilt * self._xc
            zc[-1] += self.tilt * self.x0  # x0 may be set after construction
            self.zs = PPoly.construct_fast(zc, self.tm)
        self.pitch0 = p0
        self.b = self.b_raw + self.tilt + self.pitch0
        bc = self._bc.copy()
        bc[-1] += self.tilt + self.pitch0
        self.bs = PPoly.construct_fast(bc, self.tm)

    def use_height(self, t_s: FloatArray, height_m: FloatArray) -> None:
        """Use ``height_m`` at ``t_s`` (mocap clock) where finite instead of the spline."""
        ok = np.isfinite(t_s) & np.isfinite(height_m)
        self._h_t, self._h_z = np.asarray(t_s)[ok], np.asarray(height_m)[ok]
        self._h_version += 1

    def height(self, tt: FloatArray) -> FloatArray:
        """Body height at mocap-clock times ``tt``: the spline, or the fitted height."""
        z = self.zs(tt)
        if self._h_t.size:
            i = np.clip(np.searchsorted(self._h_t, tt), 1, self._h_t.size - 1)
            near = np.minimum(np.abs(self._h_t[i] - tt), np.abs(self._h_t[i - 1] - tt))
            use = near <= 1.5e-3
            z[use] = np.interp(tt[use], self._h_t, self._h_z)
        return z

    def hip_angles(self, tf: FloatArray) -> FloatArray:
        """(n, L) hip angles at ``tf`` (cached for the last grid: the fits reuse one)."""
        if self._phi_key is not tf:
            self._phi_cache = self.phi(tf)
            self._phi_key = tf
        return self._phi_cache

    def gaps(self, tf: FloatArray, offset_s: float, ground_m: float) -> FloatArray:
        """(n, L) hip height minus rest height [m] at proprio times ``tf`` (+inf where the
        mocap does not cover ``tf + offset_s``: no contact is assumed there).

        The ground only shifts the result: the gaps above ``ground_m = 0`` are cached for the
        last (grid, offset, tilt, pitch zero, height) and the ground subtracted."""
        return self.gaps_above_zero(tf, offset_s) - ground_m

    def gaps_above_zero(self, tf: FloatArray, offset_s: float) -> FloatArray:
        """:meth:`gaps` for ground height 0, cached (read only)."""
        key = (offset_s, self.tilt, self.pitch0, self._h_version)
        if self._gap_tf is not tf or self._gap_key != key:
            tt = tf + offset_s
            z = self.height(tt)
            b = self.bs(tt)
            if COMPILED_COST and HAVE_NUMBA:
                gap = leg_gaps(z, b, self.hip_angles(tf), tt, self.hx, self.geo.hip_z_m,
                               self.geo.hip_zero_rad, self.geo.leg_radius_m, self.tm[0],
                               self.tm[-1])
                self._gap0, self._gap_tf, self._gap_key = gap, tf, key
                return gap
            hip = (z[:, None] - self.hx[None, :] * np.sin(b)[:, None]
                   + self.geo.hip_z_m * np.cos(b)[:, None])
            psi = self.hip_angles(tf) + b[:, None] + self.geo.hip_zero_rad
            gap = hip - rest_height_m(psi, self.geo.leg_radius_m)
            gap[(tt < self.tm[0]) | (tt > self.tm[-1])] = np.inf
            self._gap0, self._gap_tf, self._gap_key = gap, tf, key
        return self._gap0


def auto_pitch_smoothing(t_s: ArrayLike, pitch_rad: ArrayLike) -> int:
    """Samples of the default pitch smoother (:data:`PITCH_SMOOTHING_S`): 0 when the pitch's
    noise (:func:`white_noise_std`) is below :data:`PITCH_NOISE_MIN_RAD`."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 10 or white_noise_std(pitch_rad) < PITCH_NOISE_MIN_RAD:
        return 0
    dt = float(np.median(np.diff(t)))
    return 2 * int(round(0.5 * PITCH_SMOOTHING_S / dt)) + 1


def _smooth_segments(t: FloatArray, y: FloatArray, n: int) -> FloatArray:
    """Local quadratic (Savitzky-Golay) over ``n`` samples within each segment of the track
    (segments shorter than ``n`` kept as they are).

    Segments split where the motion capture does (:func:`.preprocess.max_mocap_gap_s`: 30 ms,
    two missing samples at 120 Hz, one at 60 Hz); samples missing inside a segment (a step
    over 1.5 median ones) are left out of the local fits, each quadratic taken over the real
    samples among the ``n`` nominal ones around it (:func:`_smooth_missing`). Before, a step
    over 1.5 median ones split the smoothing: with 10 % of a simulated 120 Hz EduBot run's
    poses missing in pairs, 8 % of its pitch samples lay in pieces shorter than the smoother
    and stayed raw (pitch error 0.49 mrad rms against the clean run's 0.42; now 0.44).
    """
    n = n + 1 - n % 2
    dt = float(np.median(np.diff(t)))
    steps = np.diff(t)
    breaks = np.flatnonzero(steps > max_mocap_gap_s(dt)) + 1
    out = y.copy()
    for a, b in zip(np.concatenate([[0], breaks]), np.concatenate([breaks, [t.size]])):
        holes = steps[a:b - 1] > 1.5 * dt
        if not np.any(holes):
            if b - a >= n:
                out[a:b] = savgol_filter(y[a:b], n, 2, mode='interp')
            continue
        # each sample's place on the nominal grid (a hole of m intervals: m - 1 missing)
        skip = np.where(holes, np.maximum(np.rint(steps[a:b - 1] / dt), 1.0), 1.0)
        slot = np.concatenate([[0], np.cumsum(skip)]).astype(np.int64)
        if slot[-1] + 1 >= n:
            out[a:b] = _smooth_missing(slot, y[a:b], n)
    return out


def _smooth_missing(slot: NDArray[np.int64], y: FloatArray, n: int) -> FloatArray:
    """Savitzky-Golay (quadratic over ``n`` nominal samples, ``mode='interp'``) of samples at
    grid places ``slot`` (increasing, some places missing): each sample's quadratic is fitted
    to the real samples of the ``n`` places centred on it (at the track's ends the first or
    last ``n``). With no place missing this is :func:`scipy.signal.savgol_filter`'s result
    (to rounding); a sample whose places hold fewer than four real ones is kept as it is."""
    size = int(slot[-1]) + 1
    h = n // 2
    start = np.clip(slot - h, 0, size - n)                       # first place of each window
    full = np.full(size, -1, dtype=np.int64)
    full[slot] = np.arange(slot.size)
    idx = full[start[:, None] + np.arange(n)[None, :]]           # (m, n), -1: missing
    real = idx >= 0
    u = np.where(real, (start[:, None] + np.arange(n)[None, :] - slot[:, None]) / h, 0.0)
    v = np.where(real, y[np.maximum(idx, 0)], 0.0)
    w = real.astype(float)
    # weighted normal equations of c0 + c1 u + c2 u^2 per sample (u in half-windows), solved
    # for c0, the value at the sample itself (u = 0)
    m0, m1, m2 = w.sum(1), (w * u).sum(1), (w * u * u).sum(1)
    m3, m4 = (w * u ** 3).sum(1), (w * u ** 4).sum(1)
    a = np.stack([np.stack([m0, m1, m2], -1), np.stack([m1, m2, m3], -1),
                  np.stack([m2, m3, m4], -1)], -2)
    rhs = np.stack([(w * v).sum(1), (w * u * v).sum(1), (w * u * u * v).sum(1)], -1)
    ok = real.sum(1) >= 4
    out = y.copy()
    if np.any(ok):
        out[ok] = np.linalg.solve(a[ok], rhs[ok][..., None])[:, 0, 0]
    return out


def _windows(tm: FloatArray, window_s: float) -> list[NDArray[np.bool_]]:
    """Masks of consecutive windows of ``window_s`` over gap-free mocap segments.

    A window holds at least 8 samples: with motion capture slower than 120 Hz (60 Hz: 6
    samples in 0.1 s) the windows are lengthened to 9 sample intervals instead of all being
    dropped.
    """
    dt = float(np.median(np.diff(tm)))
    window_s = max(window_s, 9.0 * dt)
    breaks = np.flatnonzero(np.diff(tm) > max_mocap_gap_s(dt))
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


def _flight_windows(body: _Body, t_lo: float, t_hi: float, offset_s: float, ground_m: float,
                    *, min_flight_s: float = 0.01) -> list[NDArray[np.bool_]]:
    """Masks of mocap samples between the middles of consecutive flight phases (no leg in
    contact), where the body is ballistic; windows across a mocap gap are dropped."""
    tf = np.arange(t_lo - offset_s, t_hi - offset_s, 1e-3)
    air = np.all(body.gaps(tf, offset_s, ground_m) > 0, axis=1)
    e = np.flatnonzero(np.diff(air.astype(np.int8)) != 0) + 1
    mids = []
    for i, j in zip(e[:-1], e[1:]):
        if air[i] and tf[j - 1] - tf[i] >= min_flight_s:
            mids.append(0.5 * (tf[i] + tf[j - 1]) + offset_s)
    dt = float(np.median(np.diff(body.tm)))
    out = []
    for w0, w1 in zip(mids[:-1], mids[1:]):
        k = (body.tm >= w0) & (body.tm < w1)
        if k.sum() >= 8 and not np.any(np.diff(body.tm[k]) > max_mocap_gap_s(dt)):
            out.append(k)
    return out


def _force(body: _Body, tf: FloatArray, offset_s: float, ground_m: float, model: str,
           tau_s: float) -> FloatArray:
    """Vertical leg force over the leg stiffness [m] on the grid ``tf`` (see fit models)."""
    pen = np.maximum(-body.gaps(tf, offset_s, ground_m), 0.0)
    if model == 'clipped':
        rate = np.gradient(pen, float(tf[1] - tf[0]), axis=0)
        return np.where(pen > 0, np.maximum(pen + tau_s * rate, 0.0), 0.0).sum(axis=1)
    return pen.sum(axis=1)


def _window_index(body: _Body, masks: list[NDArray[np.bool_]]
                  ) -> tuple[list[FloatArray], NDArray[np.intp], NDArray[np.intp],
                             NDArray[np.intp]]:
    """Each window's sample indices, all of them (windows are contiguous, in time order),
    the windows' sizes and start positions in that list; cached on ``body`` for the last list
    of masks (the fits evaluate one list many times)."""
    cached_masks, cached = body.window_index
    if cached_masks is masks:
        return cached
    idx = [np.flatnonzero(k) for k in masks]
    sel = np.concatenate(idx)
    sizes = np.array([i.size for i in idx])
    bounds = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    body.window_index = (masks, (idx, sel, sizes, bounds))
    return idx, sel, sizes, bounds


def _cost(body: _Body, masks: list[NDArray[np.bool_]], tf: FloatArray,
          offset_s: float, ground_m: float, *, model: str = 'linear', tau_s: float = 0.0,
          full: bool = False, per_window: bool = False, per_window_k: bool = False) -> Any:
    """Mean squared residual of the per-window dynamics fit for one (offset, ground[, tau]).

    Per window: free height, vertical velocity and stiffness (over the mass); with the
    ``'linear'`` model also one damping (the force's rate) shared by all windows. Each
    window's coefficients are projected out in closed form (window means removed, 2 x 2 normal
    equations of the contiguous samples summed with ``np.add.reduceat``), the shared one
    solved after.
    """
    step_s = float(tf[1] - tf[0])
    if COMPILED_COST and HAVE_NUMBA and not (full or per_window):
        _, sel, sizes, bounds = _window_index(body, masks)
        return cost_mse(body.gaps_above_zero(tf, offset_s), ground_m, model, tau_s, step_s,
                        tf, body.tm[sel], offset_s, body.z[sel], bounds, sizes, GRAVITY_M_S2)
    pen = _force(body, tf, offset_s, ground_m, model, tau_s)
    i1 = np.concatenate([[0.0], np.cumsum(0.5 * (pen[1:] + pen[:-1])) * step_s])
    i2 = np.concatenate([[0.0], np.cumsum(0.5 * (i1[1:] + i1[:-1])) * step_s])
    idx, sel, sizes, bounds = _window_index(body, masks)
    ts = body.tm[sel] - offset_s
    t0 = np.repeat(ts[bounds], sizes)

    def wsum(v: FloatArray) -> FloatArray:
        return np.add.reduceat(v, bounds)

    def centred(v: FloatArray) -> FloatArray:
        # the free height per window: remove each window's mean (exact, and well conditioned)
        return v - np.repeat(wsum(v) / sizes, sizes)

    # gravity's parabola from each window's start (the difference is linear in t: free)
    y = centred(body.z[sel] + 0.5 * GRAVITY_M_S2 * (ts - t0) ** 2)
    a2 = np.interp(ts, tf, i2)
    scale2 = max(float(np.max(np.abs(a2))), 1e-300)
    cols = [centred(ts - t0), centred(a2 / scale2)]
    s_col = centred(np.interp(ts, tf, i1)) if model == 'linear' else None
    n_w = len(idx)
    g = np.empty((n_w, 2, 2))
    for r in range(2):
        for c in range(r, 2):
            g[:, r, c] = g[:, c, r] = wsum(cols[r] * cols[c])
    gi = np.linalg.pinv(g, rcond=1e-12)
    xy = np.stack([wsum(c * y) for c in cols], axis=1)
    ypy = wsum(y * y) - np.einsum('wi,wij,wj->w', xy, gi, xy)
    if per_window:
        return np.maximum(ypy, 0.0) / sizes
    sse = float(ypy.sum())
    c_shared = 0.0
    xs = np.zeros_like(xy)
    if s_col is not None:
        xs = np.stack([wsum(c * s_col) for c in cols], axis=1)
        sps = wsum(s_col * s_col) - np.einsum('wi,wij,wj->w', xs, gi, xs)
        spy = wsum(s_col * y) - np.einsum('wi,wij,wj->w', xs, gi, xy)
        den = float(sps.sum())
        if den > 0:
            c_shared = float(spy.sum()) / den
            sse -= c_shared * float(spy.sum())
    mse = max(sse, 0.0) / max(sel.size, 1)
    if full:
        beta = np.einsum('wij,wj->wi', gi, xy - c_shared * xs)
        k = beta[:, 1] / scale2
        k_mean = float(np.mean(k))
        ratio = (c_shared / k_mean if k_mean > 0 else math.nan) if model == 'linear' else tau_s
        # fitted height on the grid: each grid point belongs to the window whose first sample
        # it follows (up to the next window's first sample or 1.5 sample steps after the last)
        z_raw = body.z[sel] + 0.5 * GRAVITY_M_S2 * (ts - t0) ** 2
        ybar = wsum(z_raw) / sizes
        tbar = wsum(ts - t0) / sizes
        a2bar = wsum(a2 / scale2) / sizes
        s_raw = np.interp(ts, tf, i1)
        sbar = wsum(s_raw) / sizes
        first = ts[bounds]
        last = ts[bounds + sizes - 1]
        w = np.searchsorted(first, tf, side='right') - 1
        ok = w >= 0
        dt = float(np.median(np.diff(body.tm)))
        ok[ok] &= tf[ok] <= last[w[ok]] + 1.5 * dt
        wk = w[ok]
        tt = tf[ok]
        t0w = first[wk]
        zf = (ybar[wk] + beta[wk, 0] * (tt - t0w - tbar[wk])
              + beta[wk, 1] * (np.interp(tt, tf, i2) / scale2 - a2bar[wk])
              + c_shared * (np.interp(tt, tf, i1) - sbar[wk])
              - 0.5 * GRAVITY_M_S2 * (tt - t0w) ** 2)
        height = np.full(tf.size, np.nan)
        height[ok] = zf
        if per_window_k:
            return mse, int(sel.size), ratio, tf + offset_s, height, k
        return mse, int(sel.size), ratio, tf + offset_s, height
    return mse


class _OutputError:
    """Output-error (simulation-error) refinement of the ``'clipped'`` fit (``refine='output'``).

    For given offset ``d``, ground ``g``, tilt and per-window stiffness over mass ``k``, start
    height above the ground ``h0`` and vertical velocity ``v0``, the vertical dynamics
    ``h'' = k sum_j max(0, p_j + tau p_j') - g0`` are integrated on the 1 kHz grid (Heun's
    method, all windows at once), each leg's penetration ``p_j = Q_j(t) - h(t)`` taken from the
    SIMULATED height ``h`` (``Q_j``: the leg's rest height plus the hip's height over the COM
    from the pitch); the residual is the simulated minus the measured height above the ground
    at the mocap samples (cubic Hermite between grid points). Height noise then enters the
    target only, not the force's regressors (the equation-error fit's errors in variables).
    """

    def __init__(self, body: _Body, masks: list[NDArray[np.bool_]], tf: FloatArray,
                 tau_s: float, offset_s: float, margin_s: float) -> None:
        self.body, self.tf, self.tau = body, tf, float(tau_s)
        self.step = float(tf[1] - tf[0])
        idx = [np.flatnonzero(k) for k in masks]
        self.sel = np.concatenate(idx)
        self.sizes = np.array([i.size for i in idx])
        self.bounds = np.concatenate([[0], np.cumsum(self.sizes)[:-1]])
        self.n_w = len(idx)
        self.win = np.repeat(np.arange(self.n_w), self.sizes)
        self.dt_m = float(np.median(np.diff(body.tm)))
        tm = body.tm[self.sel]
        first, last = tm[self.bounds], tm[self.bounds + self.sizes - 1]
        # grid span per window, fixed for the refinement: the offset may move by margin_s
        m = int(math.ceil(margin_s / self.step)) + 1
        self.i0 = np.floor((first - offset_s - tf[0]) / self.step).astype(int) - m
        i1 = np.ceil((last + 1.5 * self.dt_m - offset_s - tf[0]) / self.step).astype(int) + m
        if self.i0.min() < 0 or i1.max() >= tf.size:
            raise SlipDataError('output-error fit: windows outside the grid')
        self.n_steps = int(np.max(i1 - self.i0)) + 1
        self.grid_i = np.minimum(self.i0[None, :] + np.arange(self.n_steps)[:, None],
                                 tf.size - 1)  # (n_steps, W)
        self.phi = body.hip_angles(tf)
        self.hx = body.hx

    def kinematics(self, offset_s: float) -> tuple[FloatArray, FloatArray]:
        """(N, L) rest height plus the hip's height over the COM [m], and its rate [m/s]."""
        b = self.body.bs(self.tf + offset_s)
        geo = self.body.geo
        psi = self.phi + b[:, None] + geo.hip_zero_rad
        q = (rest_height_m(psi, geo.leg_radius_m) + self.hx[None, :] * np.sin(b)[:, None]
             - geo.hip_z_m * np.cos(b)[:, None])
        # the rate as the equation-error model takes it (finite differences on the grid)
        return q, np.gradient(q, self.step, axis=0)

    def simulate(self, q: FloatArray, qd: FloatArray, k: FloatArray, h0: FloatArray,
                 v0: FloatArray, sens: bool = False) -> tuple[FloatArray, ...]:
        """Heights above the ground and velocities, (n_steps, W) each, from grid ``i0``; with
        ``sens`` also their derivatives by each window's (k, h0, v0), (n_steps, 3, W) each
        (the discrete map differentiated exactly). Compiled (:mod:`._geometry_kernels`) when
        numba is installed and :data:`COMPILED_SIMULATION` is true, else the numpy loop."""
        tau, dt = self.tau, self.step
        if COMPILED_SIMULATION and HAVE_NUMBA:
            return simulate_windows(q, qd, self.i0, self.n_steps, k, h0, v0, tau, dt,
                                    GRAVITY_M_S2, sens)
        hh = np.empty((self.n_steps, self.n_w))
        vv = np.empty_like(hh)
        qg, qdg = q[self.grid_i], qd[self.grid_i]  # (n_steps, W, L)
        if sens:
            sh = np.empty((self.n_steps, 3, self.n_w))
            sv = np.empty_like(sh)

        def acc(z: FloatArray, v: FloatArray,
                s: int) -> tuple[FloatArray, FloatArray, FloatArray]:
            p = qg[s] - z[:, None]
            f = p + tau * (qdg[s] - v[:, None])
            on = (p > 0) & (f > 0)
            ff = np.where(on, f, 0.0).sum(axis=1)
            return k * ff - GRAVITY_M_S2, ff, k * on.sum(axis=1)

        def dacc(ff: FloatArray, kn: FloatArray, dz: FloatArray, dv: FloatArray) -> FloatArray:
            da = -kn * (dz + tau * dv)
            da[0] += ff
            return da

        z, v = h0.astype(float), v0.astype(float)
        a, ff, kn = acc(z, v, 0)
        if sens:
            dz = np.zeros((3, self.n_w))
            dv = np.zeros((3, self.n_w))
            dz[1] = 1.0
            dv[2] = 1.0
            da = dacc(ff, kn, dz, dv)
        last = self.n_steps - 1
        for s in range(self.n_steps):
            hh[s], vv[s] = z, v
            if sens:
                sh[s], sv[s] = dz, dv
            if s == last:
                break
            zp, vp = z + dt * v, v + dt * a
            ap, ffp, knp = acc(zp, vp, s + 1)
            z = z + 0.5 * dt * (v + vp)
            v = v + 0.5 * dt * (a + ap)
            if sens:
                dzp, dvp = dz + dt * dv, dv + dt * da
                dap = dacc(ffp, knp, dzp, dvp)
                dz = dz + 0.5 * dt * (dv + dvp)
                dv = dv + 0.5 * dt * (da + dap)
            a, ff, kn = acc(z, v, s + 1)
            if sens:
                da = dacc(ff, kn, dz, dv)
        if sens:
            return hh, vv, sh, sv
        return hh, vv

    def at_samples(self, hh: FloatArray, vv: FloatArray, offset_s: float) -> FloatArray:
        """Simulated height at the windows' mocap samples (cubic Hermite on the grid);
        ``hh``, ``vv`` (n_steps, W) or (n_steps, P, W) (sensitivities: result (P, samples))."""
        ts = self.body.tm[self.sel] - offset_s
        u = (ts - self.tf[self.i0[self.win]]) / self.step
        s = np.clip(np.floor(u).astype(int), 0, self.n_steps - 2)
        x = u - s
        w = self.win
        h00, h10 = (1 + 2 * x) * (1 - x) ** 2, x * (1 - x) ** 2
        h01, h11 = x * x * (3 - 2 * x), x * x * (x - 1)
        if hh.ndim == 3:
            return (h00 * hh[s, :, w].T + h10 * self.step * vv[s, :, w].T
                    + h01 * hh[s + 1, :, w].T + h11 * self.step * vv[s + 1, :, w].T)
        return (h00 * hh[s, w] + h10 * self.step * vv[s, w] + h01 * hh[s + 1, w]
                + h11 * self.step * vv[s + 1, w])

    def residual(self, offset_s: float, ground_m: float, tilt_rad: float, pitch0_rad: float,
                 k: FloatArray, h0: FloatArray, v0: FloatArray, sens: bool = False) -> Any:
        """Simulated minus measured height above the ground at the windows' samples [m]
        (with ``sens`` also its derivatives by each sample's window's (k, h0, v0), (3, m))."""
        self.body.set_tilt(tilt_rad, pitch0_rad)
        q, qd = self.kinematics(offset_s)
        # a trial step of the solver can make the stiff simulation diverge (its residual is
        # then not finite and the step is rejected)
        with np.errstate(over='ignore', invalid='ignore'):
            out = self.simulate(q, qd, k, h0, v0, sens=sens)
            r = self.at_samples(out[0], out[1], offset_s) - (self.body.z[self.sel] - ground_m)
        if sens:
            with np.errstate(over='ignore', invalid='ignore'):
                return r, self.at_samples(out[2], out[3], offset_s)
        return r

    def height_grid(self, offset_s: float, ground_m: float, tilt_rad: float,
                    pitch0_rad: float, k: FloatArray, h0: FloatArray,
                    v0: FloatArray) -> FloatArray:
        """The simulated body height on the grid (as ``_cost(full=True)``: input frame, NaN
        outside the windows)."""
        self.body.set_tilt(tilt_rad, pitch0_rad)
        q, qd = self.kinematics(offset_s)
        hh = self.simulate(q, qd, k, h0, v0)[0]
        tm = self.body.tm[self.sel]
        first = tm[self.bounds] - offset_s
        last = tm[self.bounds + self.sizes - 1] - offset_s
        w = np.searchsorted(first, self.tf, side='right') - 1
        ok = w >= 0
        ok[ok] &= self.tf[ok] <= last[w[ok]] + 1.5 * self.dt_m
        idx = np.flatnonzero(ok)
        s = idx - self.i0[w[ok]]
        good = (s >= 0) & (s < self.n_steps)
        out = np.full(self.tf.size, np.nan)
        out[idx[good]] = hh[s[good], w[ok][good]] + ground_m
        return out


def _merge_groups(tm: FloatArray, masks: list[NDArray[np.bool_]], merge: int
                  ) -> list[list[int]]:
    """Consecutive windows (masks over ``tm``) joined in groups of up to ``merge``: a window
    joins the group before it when its first sample follows that group's last one by no
    more than :func:`.preprocess.max_mocap_gap_s` (the track's bridged gaps: windows either
    side of two missing samples at 120 Hz are consecutive; they were not beyond 1.5 sample
    intervals, so a dropout at a window's end left the windows after it paired differently
    from the clean run's)."""
    longest = max_mocap_gap_s(float(np.median(np.diff(tm))))
    groups: list[list[int]] = []
    for i, m in enumerate(masks):
        if groups and len(groups[-1]) < merge:
            prev = np.flatnonzero(masks[groups[-1][-1]])[-1]
            if tm[np.flatnonzero(m)[0]] - tm[prev] <= longest:
                groups[-1].append(i)
                continue
        groups.append([i])
    return groups


def _refine_output_error(body: _Body, masks: list[NDArray[np.bool_]], tf: FloatArray,
                         offset_s: float, ground_m: float, tilt_rad: float,
                         pitch0_rad: float, tau_s: float, k0: FloatArray,
                         height_m: FloatArray, *, fit_offset: bool, fit_tilt: bool,
                         fit_pitch0: bool, merge: int = 1, outlier_factor: float = 2.0,
                         margin_s: float = 5e-3
                         ) -> tuple[Any, ...]:
    """Output-error refinement (:class:`_OutputError`) from the equation-error fit.

    ``masks``, ``k0`` (stiffness over mass per window) and ``height_m`` (fitted height on
    ``tf``, input frame) from the equation-error fit; consecutive gap-free windows are joined
    in groups of ``merge`` first. Levenberg-Marquardt over the globals (offset, ground, tilt,
    pitch offset) and each window's stiffness, start height and velocity (Jacobian: the window
    parameters' exactly, by the simulation's sensitivities; offset, tilt and pitch offset by
    finite differences). Windows whose residual RMS exceeds ``outlier_factor`` times the
    median window's are dropped and the fit repeated once. Returns offset, ground, tilt,
    pitch offset, residual RMS [m], the
    simulated height on ``tf`` (input frame, NaN outside the windows), the windows used and
    those dropped, the residual samples and the pitch offset's standard error [rad] (NaN
    when it is not fitted); raises :class:`SlipDataError` when the fit fails or moves the
    offset by more than ``margin_s``.
    """
    if merge > 1:
        groups = _merge_groups(body.tm, masks, merge)
        masks = [np.logical_or.reduce([masks[i] for i in grp]) for grp in groups]
        k0 = np.array([float(np.mean(k0[grp])) for grp in groups])
    oe = _OutputError(body, masks, tf, tau_s, offset_s, margin_s)
    # start: the equation-error fit's height at each window's first grid point (extrapolated
    # back from the window's first fitted point with its slope)
    hz = height_m - ground_m
    n_w = oe.n_w
    h0 = np.empty(n_w)
    v0 = np.empty(n_w)
    for w in range(n_w):
        seg = np.flatnonzero(np.isfinite(hz[oe.i0[w]:oe.i0[w] + oe.n_steps])) + oe.i0[w]
        if seg.size == 0:
            raise SlipDataError('output-error fit: no fitted height in a window')
        a = seg[0]
        v = (hz[seg[2]] - hz[seg[0]]) / (2 * oe.step) if seg.size >= 3 else 0.0
        h0[w] = hz[a] - v * (a - oe.i0[w]) * oe.step
        v0[w] = v
    ok_k = np.isfinite(k0) & (k0 > 0)
    if not ok_k.any():
        raise SlipDataError('output-error fit: no positive stiffness to start from')
    k0 = np.where(ok_k, k0, float(np.median(k0[ok_k])))
    # scaled parameters: offset ms, ground mm, tilt mrad, pitch offset mrad | k / k_ref,
    # height mm, velocity mm per 10 ms
    k_ref = float(np.median(k0))
    gi = [i for i, f in enumerate((fit_offset, True, fit_tilt, fit_pitch0)) if f]
    ng = len(gi)
    base = np.array([offset_s * 1e3, ground_m * 1e3, tilt_rad * 1e3, pitch0_rad * 1e3])
    scales = (k_ref, 1e-3, 1e-1)

    def unpack(x: FloatArray) -> tuple[float, float, float, float, FloatArray, FloatArray,
                                       FloatArray]:
        g = base.copy()
        g[gi] = x[:ng]
        r = x[ng:].reshape(3, n_w)
        return (g[0] * 1e-3, g[1] * 1e-3, g[2] * 1e-3, g[3] * 1e-3, r[0] * scales[0],
                r[1] * scales[1], r[2] * scales[2])

    def fun(x: FloatArray) -> FloatArray:
        return 1e3 * oe.residual(*unpack(x))

    rows = np.arange(oe.sel.size)

    def jac(x: FloatArray) -> FloatArray:
        r0, sr = oe.residual(*unpack(x), sens=True)
        r0 = 1e3 * r0
        jm = np.zeros((r0.size, x.size))
        for i, gl in enumerate(gi):
            if gl == 1:
                jm[:, i] = 1.0  # the ground shifts the target only (mm per mm)
                continue
            xp = x.copy()
            xp[i] += 1e-3
            jm[:, i] = (fun(xp) - r0) / 1e-3
        for blk in range(3):
            jm[rows, ng + blk * n_w + oe.win] = 1e3 * scales[blk] * sr[blk]
        return jm

    x0 = np.concatenate([base[gi], k0 / k_ref, h0 * 1e3, v0 * 1e1])
    try:
        res = least_squares(fun, x0, jac=jac, method='lm', x_scale=1.0, max_nfev=200)
    except (ValueError, np.linalg.LinAlgError) as err:
        raise SlipDataError(f'output-error fit failed: {err}') from err
    d, g, tl, p0, k, h, v = unpack(res.x)
    if not (np.all(np.isfinite(res.x)) and abs(d - offset_s) <= margin_s):
        raise SlipDataError('output-error fit: no solution near the equation-error fit')
    if outlier_factor > 0:
        # windows the simulation cannot follow: RMS above outlier_factor x the median window's
        msw = np.add.reduceat(res.fun ** 2, oe.bounds) / oe.sizes
        good = msw <= outlier_factor ** 2 * float(np.median(msw))
        if not good.all() and good.sum() >= 3:
            keep = np.flatnonzero(good)
            out = _refine_output_error(
                body, [masks[i] for i in keep], tf, offset_s, ground_m, tilt_rad, pitch0_rad,
                tau_s, k0[keep], height_m, fit_offset=fit_offset, fit_tilt=fit_tilt,
                fit_pitch0=fit_pitch0, outlier_factor=0.0, margin_s=margin_s)
            return out[:7] + (n_w - keep.size,) + out[8:]
    rms = float(np.sqrt(np.mean(res.fun ** 2))) * 1e-3
    p0_se = math.nan
    if fit_pitch0:
        # the pitch offset's standard error [rad] from the Jacobian at the solution
        jm = np.asarray(res.jac)
        var = float(res.fun @ res.fun) / max(res.fun.size - x0.size, 1)
        try:
            cov = np.linalg.pinv(jm.T @ jm) * var
            p0_se = math.sqrt(max(float(cov[gi.index(3), gi.index(3)]), 0.0)) * 1e-3
        except np.linalg.LinAlgError:
            pass
    return (d, g, tl, p0, rms, oe.height_grid(d, g, tl, p0, k, h, v), n_w, 0,
            int(res.fun.size), p0_se, float(np.median(k)))


FIT_MODELS = ('linear', 'clipped')
#: refinements of :func:`fit_ground_offset`'s equation-error fit
REFINE_MODES = ('none', 'output')
#: window length of the output-error refinement on gaits without flight phases [s] (module
#: docs): the equation-error fit's 0.1 s windows joined in pairs
OUTPUT_WINDOW_S = 0.2


class _Stage(NamedTuple):
    """One candidate of :func:`fit_ground_offset` (the pitch zero at the prior, or free)."""

    d: float
    g: float
    tilt: float
    p0: float
    mse: float
    n_samples: int
    ratio: float
    h_t: FloatArray
    h_z: FloatArray
    n_used: int
    n_drop: int
    p0_se: float
    refined: bool
    k_per_kg: float = math.nan
    eq_mse: float = math.nan  # the equation-error fit's, before the refinement

    # what :func:`prefer_fit` compares
    @property
    def rms_m(self) -> float:
        return math.sqrt(self.mse)

    @property
    def unrefined(self) -> bool:
        return not self.refined

    @property
    def equation_rms_m(self) -> float:
        return math.sqrt(self.eq_mse)


def fit_ground_offset(geometry: LegGeometry, joint_names: tuple[str, ...], joint_t_s: ArrayLike,
                      joint_position: ArrayLike, joint_velocity: ArrayLike,
                      mocap_t_s: ArrayLike, height_m: ArrayLike, pitch_rad: ArrayLike, *,
                      initial_offset_s: float = 0.0, offset_range_s: float = 0.015,
                      ground_range_m: tuple[float, float] = (-0.05, 0.05),
                      window_s: float = 0.1, min_windows: int = 3, windows: str = 'flight',
                      model: str = 'clipped', tau_s: float | None = None,
                      fix_tau: bool | None = None, fix_offset: bool = False,
                      outlier_factor: float = 2.0, x_m: ArrayLike | None = None,
                      fit_tilt: bool | None = None,
                      tilt_range_rad: float = math.radians(0.6),
                      tilt_from_strides: bool = True,
                      fit_pitch_offset: bool = True,
                      pitch_offset_rad: float = 0.0,
                      pitch_offset_range_rad: float = PITCH_OFFSET_RANGE_RAD,
                      pitch_smoothing: int | None = 0,
                      refine: str | None = None,
                      output_window_s: float = OUTPUT_WINDOW_S) -> GeometryFit:
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
    windows : str
        ``'flight'``: one window per stance, between the middles of the flight phases around
        it (ballistic ends); ``'fixed'`` (or too few flights, e.g. gaits without aerial
        phases): consecutive windows of ``window_s``.
    model : str
        Leg force over the stiffness: ``'clipped'`` (per leg penetration plus ``tau`` times
        its rate, clipped at zero: a leg cannot pull) or ``'linear'`` (sum of the legs'
        penetrations plus one free damping coefficient on its rate, shared by the windows).
        A spoke model (compression towards a pinned toe / rolling contact point) was tried
        and fitted worse on the simulator (feet slide, the leg bends).
    tau_s : float, optional
        Leg damping over stiffness [s] (``'clipped'``): the start of its fit, or
        its value with ``fix_tau``; default ``geometry.leg_damping_time_s`` (fixed), or 5 ms
        fitted when that is None.
    fix_tau : bool, optional
        Default: fixed when the damping time is known (given or in ``geometry``).
    fix_offset : bool
        Keep ``initial_offset_s`` (a known offset) and fit the ground height (and tau) only.
    outlier_factor : float
        Windows whose residual RMS exceeds this times the median window's (at the coarse
        optimum) are dropped before the final fit (``GeometryFit.dropped_windows``).
    x_m : array_like, shape (m,), optional
        COM position along the travel direction [m] (same frame as the heights). With it the
        ground's slope along x is fitted too (``fit_tilt``): a world frame levelled on the COM
        path is tilted by the path's slope (a body height drifting over the run, a start-up
        transient), which biases the front and rear hip heights against each other; the
        contacts see the real ground.
    fit_tilt : bool, optional
        Default: True when ``x_m`` is given.
    tilt_from_strides : bool
        With ``fit_tilt``, take the slope from whole strides (:func:`stride_slope_rad`, the
        stride period from the hips' mean speed) when the run has enough steady state, and
        fit it only otherwise (``GeometryFit.tilt_source`` 'strides' or 'fitted'; module
        docs).
    tilt_range_rad : float
        Half-width of the coarse tilt scan [rad].
    pitch_smoothing : int
        Samples of the local quadratic through the pitch (0: none, the default; None: as
        :func:`leg_contacts` does, :func:`auto_pitch_smoothing`). Smoothing the pitch here
        changed nothing on the simulated edges (module docs).
    fit_pitch_offset : bool
        Try the rigid body's pitch zero free beside ``pitch_offset_rad`` (module docs);
        False: keep ``pitch_offset_rad``.
    pitch_offset_rad : float
        The prior (or known) pitch zero [rad]: the correction added to the pitch.
    pitch_offset_range_rad : float
        Half-width of the zero's scan around the zero that levels the median pitch [rad].
    refine : str, optional
        ``'output'`` (the default with ``model='clipped'``): the equation-error fit above is
        refined by an output-error fit (module docs): the vertical dynamics are simulated
        with each leg's penetration taken from the simulated height, and offset, ground, tilt
        and the windows' stiffness, start height and velocity minimise the simulated minus
        the measured height (falls back to the equation-error fit when that fails).
        ``'none'``: the equation-error fit only (the default with ``model='linear'``).
    output_window_s : float
        Window length of the output-error fit when the windows are ``window_s`` long (no
        flight phases): consecutive gap-free windows are joined to about this length.

    Returns
    -------
    GeometryFit
        With the output-error refinement ``rms_m`` is its residual (simulated minus
        measured height), ``windows`` its windows and ``height_m`` the simulated height.
    """
    if tau_s is None:
        tau_s = geometry.leg_damping_time_s
        if fix_tau is None:
            fix_tau = tau_s is not None
        if tau_s is None:
            tau_s = 0.005
    elif fix_tau is None:
        fix_tau = False
    if refine is None:
        refine = 'output' if model == 'clipped' else 'none'
    if refine not in REFINE_MODES:
        raise SlipDataError(f'refine must be one of {REFINE_MODES}, got {refine!r}')
    if refine == 'output' and model != 'clipped':
        raise SlipDataError("refine='output' needs model='clipped'")
    if model not in FIT_MODELS:
        raise SlipDataError(f'model must be one of {FIT_MODELS}, got {model!r}')
    if fit_tilt is None:
        fit_tilt = x_m is not None
    if fit_tilt and x_m is None:
        raise SlipDataError('fit_tilt needs x_m (COM positions along the travel direction)')
    body = _Body(geometry, tuple(joint_names), joint_t_s, joint_position, joint_velocity,
                 mocap_t_s, height_m, pitch_rad, x_m, pitch_smoothing)
    tilt_source = 'fitted' if fit_tilt else 'none'
    masks = _windows(body.tm, window_s)
    lo_j, hi_j = body.t_j[0], body.t_j[-1]
    t_lo = max(body.tm[0], lo_j + initial_offset_s + offset_range_s + 0.02)
    t_hi = min(body.tm[-1], hi_j + initial_offset_s - offset_range_s - 0.02)
    if t_hi - t_lo < min_windows * window_s:
        raise SlipDataError(f'geometry fit: mocap and hip angles overlap for {t_hi - t_lo:.2f} '
                            f's, need >= {min_windows * window_s:.2f} s')
    keep = (body.tm >= t_lo) & (body.tm <= t_hi)
    masks = [k & keep for k in masks]
    masks = [k for k in masks if k.sum() >= 8]
    if len(masks) < min_windows:
        raise SlipDataError(f'geometry fit: {len(masks)} gap-free mocap windows of {window_s} s '
                            f'overlap the hip angles, need >= {min_windows}')
    tau_fit = model != 'linear' and not fix_tau
    # one proprioception-time grid for every candidate offset (hip angles evaluated once);
    # force before the mocap span is zero, and the integrals' start only adds per-window
    # linear terms, which are free
    reach = offset_range_s + 0.015
    tf = np.arange(t_lo - initial_offset_s - reach, t_hi - initial_offset_s + reach, 1e-3)

    def f(d: float, g: float, tau: float = tau_s) -> float:
        return _cost(body, masks, tf, d, g, model=model, tau_s=max(tau, 0.0))

    # coarse stage: the final model when the damping time is known, else the linear model
    # (damping a free linear coefficient); 5 ms offset steps
    coarse_model = model if fix_tau else 'linear'
    coarse_step = 5e-3

    def f_coarse(d: float, g: float) -> float:
        # with the damping time unknown, the linear model (damping a free linear coefficient)
        return _cost(body, masks, tf, d, g, model=coarse_model, tau_s=tau_s)

    def best_ground(d: float, lo: float, hi: float) -> tuple[float, float]:
        r = minimize_scalar(lambda g: f_coarse(d, g), method='bounded', bounds=(lo, hi),
                            options={'xatol': 3e-4})
        return float(r.x), float(r.fun)

    def coarse(d0: float, g_lo: float, g_hi: float) -> tuple[float, float]:
        # for each offset on a coarse grid the best ground, then 1 ms steps around the best
        d_b, g_b = d0, 0.5 * (g_lo + g_hi)
        for step, half in ((coarse_step, offset_range_s), (1e-3, 5e-3)):
            grid = d_b + np.arange(-half, half + 1e-9, step)
            cand = [(d, *best_ground(d, g_lo, g_hi)) for d in grid]
            d_b, g_b, _ = min(cand, key=lambda c: c[2])
            g_lo, g_hi = g_b - 0.01, g_b + 0.01
        return d_b, g_b

    # coarse: the ground on a 2 mm grid at the initial offset, then the offset grid
    d_best = float(initial_offset_s)
    g_grid = np.arange(ground_range_m[0], ground_range_m[1] + 1e-9, 2e-3)
    g_best = float(min(g_grid, key=lambda g: f_coarse(d_best, g)))
    prior = float(pitch_offset_rad)
    body.set_tilt(0.0, prior)
    dropped = 0
    flight = False
    for it in range(2):
        if not fix_offset:
            half_g = 0.015 if it == 0 else 0.01
            lo, hi = g_best - half_g, g_best + half_g
            d_best, g_best = coarse(initial_offset_s, lo, hi)
        else:
            g_best = best_ground(d_best, g_best - 5e-3, g_best + 5e-3)[0]
        if it == 0 and windows == 'flight':
            fm = _flight_windows(body, t_lo, t_hi, d_best, g_best)
            if len(fm) >= min_windows:
                masks = fm
                flight = True
        # windows the model cannot follow (a foot sliding, the body touching the ground, a
        # tracking glitch): RMS residual above outlier_factor x the median window's
        msw = _cost(body, masks, tf, d_best, g_best, model=coarse_model, tau_s=tau_s,
                    per_window=True)
        good = msw <= outlier_factor ** 2 * float(np.median(msw))
        if good.all() or good.sum() < min_windows:
            break
        masks = [k for k, ok in zip(masks, good) if ok]
        dropped += int((~good).sum())
    def scan(values: FloatArray, set_value: Any, d: float, g: float,
             half_m: float = 6e-3) -> tuple[float, float]:
        # a parameter scanned at offset d (best ground each), the parabola through the best
        # three refining it; returns it and the ground there
        costs = []
        for v in values:
            set_value(float(v))
            costs.append(best_ground(d, g - half_m, g + half_m))
        i = int(np.argmin([c[1] for c in costs]))
        best, g = float(values[i]), costs[i][0]
        if 0 < i < values.size - 1:
            c0, c1, c2 = costs[i - 1][1], costs[i][1], costs[i + 1][1]
            den = c0 - 2 * c1 + c2
            if den > 0:
                best += 0.5 * (c0 - c2) / den * float(values[1] - values[0])
        set_value(best)
        return best, best_ground(d, g - 6e-3, g + 6e-3)[0]

    def set_tilt(v: float) -> None:
        body.set_tilt(v)

    def set_pitch0(v: float) -> None:
        body.set_tilt(body.tilt, v)

    tilt_grid = np.linspace(-tilt_range_rad, tilt_range_rad, 7)
    tilt0 = 0.0
    stride_slope = None
    if fit_tilt and tilt_from_strides and not flight:
        # the stride period from the hips' mean speed (measured velocities: positions may
        # wrap), when they turn (a rotating-leg gait)
        rate = float(np.mean(np.abs(np.mean(body.phi(body.t_j, 1), axis=0))))
        if rate > 1.0:
            stride_slope = stride_slope_rad(body.tm, body.z_raw, body.x, body.b_raw,
                                            2 * math.pi / rate)
    if stride_slope is not None:
        # without flight phases the body-height dynamics pin the ground's slope weakly (0.5-0.7
        # mrad off on simulated pace and walk, against 0.05-0.2 mrad from whole strides; with
        # flight phases the ballistic windows pin it: running and jogging fit it)
        tilt0, fit_tilt, tilt_source = stride_slope, False, 'strides'
        body.set_tilt(tilt0)
    tilt_best = tilt0

    def tilt_free(free_p0: bool) -> bool:
        # a slope from whole strides is held with the prior zero; with the zero free the slope
        # is free as well (the two both turn the pitch: held at the strides' slope, a free zero
        # took up a pace start-up transient's pitch and was kept 0.35 deg off a level rigid
        # body)
        return bool(fit_tilt) or (free_p0 and tilt_source == 'strides')

    if fit_tilt:
        # the ground's slope: a scan at the coarse offset
        tilt_best, g_best = scan(tilt_grid, set_tilt, d_best, g_best)
    # Nelder-Mead in ms, mm, mrad (tilt, pitch offset) and ms (tau)
    x0 = ([d_best * 1e3, g_best * 1e3, tilt_best * 1e3, prior * 1e3]
          + ([tau_s * 1e3] if tau_fit else []))

    def nelder_mead(free_p0: bool, ref: list[float]) -> list[float]:
        free = ([not fix_offset, True, tilt_free(free_p0), free_p0]
                + ([True] if tau_fit else []))
        ix = [i for i, fr in enumerate(free) if fr]

        def obj(v: FloatArray) -> float:
            x = list(ref)
            for i, vi in zip(ix, v):
                x[i] = vi
            # stay near the start (ms, mm, mrad) and keep the damping ratio physical
            out = max(abs(x[0] - ref[0]) - 10.0, abs(x[1] - ref[1]) - 10.0,
                      abs(x[2] - ref[2]) - 5.0, abs(x[3] - ref[3]) - 10.0, 0.0)
            if tau_fit:
                out = max(out, -x[4], x[4] - 50.0)
            if out > 0:
                return 1e6 * (1.0 + out)
            body.set_tilt(x[2] * 1e-3, x[3] * 1e-3)
            return f(x[0] * 1e-3, x[1] * 1e-3, x[4] * 1e-3 if tau_fit else tau_s) * 1e8

        start = np.array([ref[i] for i in ix])
        simplex = [start] + [start + 2.0 * np.eye(len(ix))[i] for i in range(len(ix))]
        res = minimize(obj, start, method='Nelder-Mead',
                       options={'xatol': 0.02, 'fatol': 1e-6, 'initial_simplex': simplex})
        x = list(ref)
        for i, vi in zip(ix, res.x):
            x[i] = float(vi)
        return x

    def final(free_p0: bool, x: list[float]) -> _Stage:
        # the equation-error fit at ``x``, then its output-error refinement
        d, g, tilt, p0 = x[0] * 1e-3, x[1] * 1e-3, x[2] * 1e-3, x[3] * 1e-3
        tau = max(x[4] * 1e-3, 0.0) if tau_fit else tau_s
        body.set_tilt(tilt, p0)
        mse, n_s, ratio, h_t, h_z, k_w = _cost(body, masks, tf, d, g, model=model, tau_s=tau,
                                               full=True, per_window_k=True)
        n_used, n_drop, refined, p0_se = len(masks), 0, False, math.nan
        k_kg = float(np.median(k_w)) if len(k_w) else math.nan
        eq_mse = mse
        if refine == 'output':
            try:
                out = _refine_output_error(
                    body, masks, tf, d, g, tilt, p0, tau, k_w, h_z, fit_offset=not fix_offset,
                    fit_tilt=tilt_free(free_p0), fit_pitch0=free_p0,
                    outlier_factor=outlier_factor, margin_s=15e-3 if free_p0 else 5e-3,
                    merge=1 if flight else max(1, int(round(output_window_s / window_s))))
            except SlipDataError:
                out = None  # keep the equation-error fit
            if out is not None:
                d, g, tilt, p0, rms, h_z, n_used, n_drop, n_s, p0_se, k_kg = out
                mse = rms * rms
                h_t = tf + d
                refined = True
        return _Stage(d, g, tilt, p0, mse, n_s, ratio, h_t, h_z, n_used, n_drop, p0_se,
                      refined, k_kg, eq_mse)

    def prefers(alt: _Stage, base: _Stage, k: int) -> bool:
        # the Bayesian information criterion with ``k`` more parameters in ``alt``,
        # n ln(mse_base / mse_alt) > k ln n, on comparable residuals (prefer_fit: a refined
        # and an unrefined stage by their equation-error fits')
        n_s = max(min(base.n_samples, alt.n_samples), 2)
        return alt.mse > 0 and prefer_fit(alt, base, n_s ** (-k / (2.0 * n_s)))

    x_prior = nelder_mead(False, x0)
    fits = [final(False, x_prior)]
    if tilt_source == 'strides':
        # the slope fitted beside the strides' one (the fit before it): kept when it lowers
        # the residual by more than a parameter's price. A rigid body's pitch zero a few
        # tenths of a degree off (below what the free zero resolves) is partly taken up by a
        # free slope (both turn the pitch); held at the strides' slope, a pace run with a
        # rigid body 0.3 deg off lost its offset (2.9 ms) and every edge
        fit_tilt = True
        body.set_tilt(0.0, prior)
        tb, gb = scan(tilt_grid, set_tilt, d_best, g_best)
        xf = nelder_mead(False, [d_best * 1e3, gb * 1e3, tb * 1e3, prior * 1e3]
                         + ([tau_s * 1e3] if tau_fit else []))
        fitted = final(False, xf)
        # ... and stays within the scan's half-width of the strides' slope (beyond it the fit
        # has left what it searched: an outside review's pace at 60 Hz kept a fitted slope
        # 34 mrad off, against 0.13 mrad from the strides)
        if prefers(fitted, fits[0], 1) and \
                abs(fitted.tilt - stride_slope) <= tilt_range_rad:
            fits, x_prior, tilt_source = [fitted], xf, 'fitted'
        else:
            fit_tilt = False
    pitch_fitted = False
    if fit_pitch_offset and pitch_offset_range_rad > 0 and np.ptp(body.hx) > 0.01:
        # The rigid body's pitch zero against the hip line (module docs), tried beside the
        # prior and kept when it lowers the residual by more than the Bayesian information
        # criterion's price of a parameter, n ln(mse_prior / mse_free) > ln n (on simulated
        # walk a free zero scatters by 0.1-0.2 deg, 4 ms at the rear hip's slow crossing;
        # the prior's frame is within 0.7 mrad). Its start: a scan at the prior fit's offset
        # at the zero that levels the median pitch: the offset searched there, a scan of
        # the zero (1 deg steps, best ground each, parabola refined) and the offset searched
        # again when it moved (with a rigid body 3 deg off, a walk's offset at the prior
        # was 36 to 68 ms off). Hips all at one place along the body (a two-leg synthetic
        # body) leave it a second ground height: not tried.
        rng = float(pitch_offset_range_rad)
        step = math.radians(1.0)

        def free_zero(restart: bool) -> _Stage:
            # the zero scanned around the centre and the fit refined with it free; from the
            # prior fit's ground, slope and offset, or (restart) from a level ground at the
            # centre with the offset searched again, as the prior fit started
            g_b, tl_b, d_b = x_prior[1] * 1e-3, x_prior[2] * 1e-3, x_prior[0] * 1e-3
            if restart:
                tl_b = tilt0
            centre = prior + float(np.clip(-np.median(body.b_raw) - tl_b - prior,
                                           -PITCH_OFFSET_CENTRE_RAD, PITCH_OFFSET_CENTRE_RAD))
            body.set_tilt(tl_b, centre)
            if restart:
                g_b = float(min(g_grid, key=lambda g: f_coarse(initial_offset_s, g)))
            if abs(centre - prior) > 0.5 * step and not fix_offset:
                half = 0.015
                d_b, g_b = coarse(initial_offset_s, g_b - half, g_b + half)
            p0_s, g_b = scan(centre + np.arange(-rng, rng + 1e-12, step), set_pitch0, d_b, g_b,
                             half_m=8e-3)
            if abs(p0_s - centre) > 0.5 * step and not fix_offset:
                d_b, g_b = coarse(initial_offset_s, g_b - 0.01, g_b + 0.01)
            if tilt_free(True):
                tl_b, g_b = scan(tilt_grid, set_tilt, d_b, g_b)
            x1 = list(x_prior)
            x1[:4] = [d_b * 1e3, g_b * 1e3, tl_b * 1e3, p0_s * 1e3]
            return final(True, nelder_mead(True, x1))

        alt = free_zero(False)
        if abs(float(np.median(body.b_raw)) + prior) > 0.5 * step:
            # Far from the prior, its fit's ground, slope and offset may have absorbed the
            # wrong zero (a rigid body 6 deg off: ground 20 mm high, slope 15 mrad, a walk's
            # offset 82 ms off; running's offset was found from there, not from a restart):
            # both starts, the better fit kept
            other = free_zero(True)
            if prefer_fit(other, alt):
                alt = other
        fixed = fits[0]
        if abs(alt.p0 - prior) < max(PITCH_OFFSET_MIN_RAD, 3.0 * alt.p0_se):
            better = False  # within the free zero's own scatter, or its standard error's
        else:
            # the price of each parameter the free fit adds (the zero, and the slope when
            # the prior's came from whole strides)
            better = prefers(alt, fixed, 1 + (tilt_free(True) and not fit_tilt))
        if better:
            fits = [alt]
            pitch_fitted = True
    st = fits[0]
    dropped += st.n_drop
    body.set_tilt(st.tilt, st.p0)
    return GeometryFit(offset_s=st.d, ground_m=st.g, rms_m=math.sqrt(st.mse),
                       windows=st.n_used, damping_ratio_s=st.ratio, height_t_s=st.h_t,
                       height_m=st.h_z, dropped_windows=dropped, tilt_rad=st.tilt,
                       tilt_x0_m=body.x0, pitch_offset_rad=st.p0,
                       pitch_offset_fitted=pitch_fitted,
                       pitch_offset_se_rad=st.p0_se if pitch_fitted else math.nan,
                       tilt_source=tilt_source, stiffness_per_kg=st.k_per_kg,
                       samples=st.n_samples, flight=flight,
                       unrefined=refine == 'output' and not st.refined,
                       equation_rms_m=math.sqrt(st.eq_mse))


def offset_ground_grid(geometry: LegGeometry, joint_names: tuple[str, ...],
                       joint_t_s: ArrayLike, joint_position: ArrayLike,
                       joint_velocity: ArrayLike, mocap_t_s: ArrayLike, height_m: ArrayLike,
                       pitch_rad: ArrayLike, *, initial_offset_s: float,
                       offset_range_s: float = 0.2,
                       ground_range_m: tuple[float, float] = (-0.25, 0.25),
                       offset_step_s: float = 5e-3, ground_step_m: float = 2e-3,
                       window_s: float = 0.1, max_windows: int = 60,
                       pitch_offset_rad: float = 0.0, x_m: ArrayLike | None = None
                       ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The coarse stage's cost of :func:`fit_ground_offset` on a whole grid of stream offsets
    and ground heights: ``(offsets, grounds, cost)``, ``cost[i, j]`` the mean squared residual
    of the body's vertical dynamics at ``(offsets[i], grounds[j])``.

    :func:`fit_ground_offset` picks the ground at its start and searches the offset near that
    ground only; from a start far off (a cross-correlation 80 ms off, no hip efforts) that
    ground is far off too (143 mm on an outside review's run) and the true pair is never
    visited. This grid visits every pair, for a start to fit from. The model is the coarse
    stage's (the geometry's damping time when known, else the linear model's free damping);
    level ground, the pitch zero ``pitch_offset_rad``; at most ``max_windows`` windows of
    ``window_s``, spread over the run (the cost of a grid point grows with the samples).
    Raises SlipDataError when the streams overlap too little."""
    body = _Body(geometry, tuple(joint_names), joint_t_s, joint_position, joint_velocity,
                 mocap_t_s, height_m, pitch_rad, x_m, 0)
    masks = _windows(body.tm, window_s)
    t_lo = max(body.tm[0], body.t_j[0] + initial_offset_s + offset_range_s + 0.02)
    t_hi = min(body.tm[-1], body.t_j[-1] + initial_offset_s - offset_range_s - 0.02)
    keep = (body.tm >= t_lo) & (body.tm <= t_hi)
    masks = [k & keep for k in masks]
    masks = [k for k in masks if k.sum() >= 8]
    if len(masks) < 3:
        raise SlipDataError(f'offset grid: {len(masks)} mocap windows overlap the hip angles '
                            f'over +-{offset_range_s:g} s, need >= 3')
    if len(masks) > max_windows:
        masks = [masks[int(i)] for i in np.linspace(0, len(masks) - 1, max_windows)]
    tau = geometry.leg_damping_time_s
    model = 'clipped' if tau is not None else 'linear'
    reach = offset_range_s + 0.015
    tf = np.arange(t_lo - initial_offset_s - reach, t_hi - initial_offset_s + reach, 1e-3)
    body.set_tilt(0.0, float(pitch_offset_rad))
    offsets = initial_offset_s + np.arange(-offset_range_s, offset_range_s + 1e-9,
                                           offset_step_s)
    grounds = np.arange(ground_range_m[0], ground_range_m[1] + 1e-9, ground_step_m)
    cost = np.array([[_cost(body, masks, tf, float(d), float(g), model=model,
                            tau_s=tau or 0.0) for g in grounds] for d in offsets])
    return offsets, grounds, cost


def leg_contacts(geometry: LegGeometry, joint_names: tuple[str, ...], joint_t_s: ArrayLike,
                 joint_position: ArrayLike, joint_velocity: ArrayLike, mocap_t_s: ArrayLike,
                 height_m: ArrayLike, pitch_rad: ArrayLike, *, offset_s: float,
                 ground_m: float, step_s: float = 5e-4, fit: GeometryFit | None = None,
                 x_m: ArrayLike | None = None, tilt_rad: float | None = None,
                 rearm_m: float | None = None, pitch_smoothing: int | None = None,
                 pitch_offset_rad: float | None = None, pool_steady: bool = True,
                 info: dict[str, Any] | None = None
                 ) -> tuple[dict[str, FloatArray], FloatArray]:
    """Per-leg contact intervals where the hip is below the leg's rest height, (k, 2) [s].

    Times are in the proprioception clock, over the span the mocap (shifted by ``offset_s``)
    and the hip angles cover; edges are the interpolated zero crossings of hip height minus
    rest height. A contact cut by the span's ends or by a mocap gap is kept, clipped there.
    Arguments as :func:`fit_ground_offset`; with ``fit`` (its result) the body height is the
    fitted one (noise-free, ballistic in flight) where the fit covers it, else the spline
    through the samples. ``tilt_rad`` (default: ``fit.tilt_rad``, else 0) is the ground's
    slope along +x (:class:`GeometryFit`); a nonzero tilt needs ``x_m``. A leg that has
    lifted off lands again only after its lowest point has cleared the ground by ``rearm_m``
    (default ``geometry.rearm_clearance_m``): a hysteresis against contacts chattering on
    height noise, and a leaning leg that has sprung off while its rest shape still reaches
    below the ground does not count as landed. ``pitch_offset_rad`` (default: ``fit.
    pitch_offset_rad``, else 0) is added to the pitch; ``pitch_smoothing`` None (default)
    smooths a noisy pitch (:func:`auto_pitch_smoothing`), 0 leaves it as it is.

    ``pool_steady`` (with ``fit``, on rotating legs): in steady state each edge is pooled with
    the same leg's same edges at other strides, weighted by how sharply its own crossing is
    determined (:func:`_pool_edges`); ``info`` (a dict) receives what that did.

    Returns
    -------
    contacts : dict
        ``{leg: (k, 2)}`` [s].
    unknown : ndarray, shape (u, 2)
        Intervals where contact is not known (before and after the span, mocap gaps) [s];
        :func:`single_support` drops pieces that touch them.
    """
    if tilt_rad is None:
        tilt_rad = fit.tilt_rad if fit is not None else 0.0
    if pitch_offset_rad is None:
        pitch_offset_rad = fit.pitch_offset_rad if fit is not None else 0.0
    rearm = float(geometry.rearm_clearance_m if rearm_m is None else rearm_m)
    if tilt_rad != 0.0 and x_m is None:
        raise SlipDataError(f'a ground tilt of {tilt_rad:.2e} rad needs x_m (COM positions)')
    body = _Body(geometry, tuple(joint_names), joint_t_s, joint_position, joint_velocity,
                 mocap_t_s, height_m, pitch_rad, x_m, pitch_smoothing)
    if fit is not None and fit.tilt_rad != 0.0:
        body.x0 = fit.tilt_x0_m
    body.set_tilt(float(tilt_rad), float(pitch_offset_rad))
    if fit is not None and fit.height_m.size:
        body.use_height(fit.height_t_s, fit.height_m)
    t0 = max(body.tm[0] - offset_s, body.t_j[0])
    t1 = min(body.tm[-1] - offset_s, body.t_j[-1])
    if t1 - t0 < 10 * step_s:
        raise SlipDataError(f'mocap (offset {offset_s:.3f} s) and hip angles overlap for '
                            f'{max(t1 - t0, 0.0):.3f} s only')
    tf = np.arange(t0, t1, step_s)
    dt = float(np.median(np.diff(body.tm)))
    gi = np.flatnonzero(np.diff(body.tm) > max_mocap_gap_s(dt))
    unknown = [(-np.inf, float(tf[0]))] + [
        (float(body.tm[i] - offset_s), float(body.tm[i + 1] - offset_s)) for i in gi] + [
        (float(tf[-1]), np.inf)]
    known = np.ones(tf.size, dtype=bool)
    for a, b in unknown[1:-1]:
        known &= ~((tf > a) & (tf < b))
    gaps = body.gaps(tf, offset_s, ground_m)
    out: dict[str, FloatArray] = {}
    for j, leg in enumerate(body.legs):
        s = gaps[:, j]
        on = (s < 0) & known
        e = np.flatnonzero(on[1:] != on[:-1])
        # interpolate crossings of s where both samples are known, else take the sample time
        tc = tf[e + 1].astype(float)
        both = (known[e] & known[e + 1] & np.isfinite(s[e]) & np.isfinite(s[e + 1])
                & (s[e] != s[e + 1]))
        tc[both] = tf[e[both]] + step_s * s[e[both]] / (s[e[both]] - s[e[both] + 1])
        starts = list(tc[on[e + 1]])
        ends = list(tc[~on[e + 1]])
        if on[0]:
            starts.insert(0, float(tf[0]))
        if on[-1]:
            ends.append(float(tf[-1]))
        iv = np.array(list(zip(starts, ends)), dtype=float).reshape(-1, 2)
        out[leg] = _rearmed(iv, tf, s, known, rearm)
    if pool_steady and fit is not None:
        _pool_edges(body, tf, gaps, known, out, offset_s, fit.rms_m, info)
    return out, np.array(unknown, dtype=float)


#: an edge's crossing rate is the gap's change over this span on its in-contact side [s]
POOL_RATE_SPAN_S = 5e-3
#: floor of the stride-to-stride scatter of an edge's hip angle, as time at the edge's hip
#: speed [s]: an edge determined better than this keeps most of its own estimate
POOL_MIN_SCATTER_S = 1e-3
#: edges of one leg and kind needed in steady state before they are pooled
POOL_MIN_EDGES = 3
#: no edge is moved further than this [s]: pooling takes out the noise of flat crossings
#: (simulated walk: up to 9 ms); edges further apart than that disagree for another reason
#: (three noisy 3 s pace lift-offs, two of them 80-93 ms off, moved the good one 66 ms)
POOL_MAX_MOVE_S = 0.015
#: an edge further than this many of its own standard deviations from its strides' median
#: phase is taken as a real change (a speed change, a stumble) and not moved
POOL_MAX_SIGMAS = 4.0


def _pool_edges(body: _Body, tf: FloatArray, gaps: FloatArray, known: NDArray[np.bool_],
                out: dict[str, FloatArray], offset_s: float, height_rms_m: float,
                info: dict[str, Any] | None) -> None:
    """Pool each steady-state edge with the same leg's same edges at other strides (in place).

    An edge is a zero crossing of the gap (hip height minus rest height); a height error dh
    moves it by dh / r, with r the gap's rate on the in-contact side. A leg that lands while
    the others carry the body sinks slowly, so a fraction of a millimetre of mocap noise moves
    its touchdown by several milliseconds (simulated walk: a front leg 5-9 ms late), where a
    leg landing under load is within a millisecond. In steady state the motion repeats with
    the gait period, so a leg lands and lifts off at the same phase every stride (simulated
    walk: within 0.5 ms). For each leg and kind of edge (touchdown, lift-off) over the steady
    part: the phases (times less whole periods), their median, and a shrinkage toward it as
    in a random-effects model: the edges' own variance is the height error (the fit's
    residual RMS and the pitch noise at the hip) over the median rate of those edges (one rate
    for all: a rate read at an edge that is off is read at the wrong place, and weights from it
    pulled good edges toward bad ones), the stride-to-stride variance is what the phases'
    robust spread (1.4826 MAD) leaves beyond it, at least :data:`POOL_MIN_SCATTER_S`. An edge
    further than :data:`POOL_MAX_SIGMAS` own standard deviations from the median (a speed
    change, a stumble) is not moved, nor one that would move more than
    :data:`POOL_MAX_MOVE_S` or cross its neighbour. Only runs whose hips turn: each leg's
    period is the time its hip takes for whole turns over the steady part
    (:func:`.steady.steady_start_s`, from the pitch). Contacts cut by the span's ends or by
    mocap gaps are left out.
    """
    v = body.phi(body.t_j, 1)  # the measured hip speeds
    if not np.all(np.abs(np.mean(v, axis=0)) > 1.0) or not math.isfinite(height_rms_m):
        return
    period = 2 * math.pi / float(np.mean(np.abs(np.mean(v, axis=0))))
    t_steady = steady_start_s(body.tm, body.b_raw, period) - offset_s
    if not math.isfinite(t_steady):
        return
    step = float(tf[1] - tf[0])
    n_span = max(1, int(round(POOL_RATE_SPAN_S / step)))
    sigma_b = white_noise_std(body.b_raw)
    moved = []
    for j, leg in enumerate(body.legs):
        iv = out[leg]
        s_j = body.t_j >= t_steady
        if iv.shape[0] < POOL_MIN_EDGES or s_j.sum() < 10:
            continue
        # the leg's period: whole turns of its hip over the steady part, from the angles
        # (the spline's are unwrapped; integrated speeds drift: 0.3 % at 100 Hz on a
        # duty-0.8 clock); the running maximum, as the hip may dip back for a sample
        q_j = body.phi(body.t_j[s_j])[:, j]
        turn = np.maximum.accumulate(np.sign(np.mean(v[s_j, j])) * (q_j - q_j[0]))
        n_turns = int(turn[-1] // (2 * math.pi))
        if n_turns < 1:
            continue
        period_j = float(np.interp(2 * math.pi * n_turns, turn, body.t_j[s_j])
                         - body.t_j[s_j][0]) / n_turns
        sig_h = math.hypot(height_rms_m, sigma_b * float(body.hx[j]))
        for col, side in ((0, 1), (1, -1)):  # touchdown: contact after; lift-off: before
            t = iv[:, col]
            i = np.searchsorted(tf, t)
            k = i + n_span if side > 0 else i - 1 - n_span
            # crossings inside the span (a contact cut at its ends has an edge on tf[0] or
            # tf[-1]), with the gap known around them and where the rate is read
            inner = ((t >= t_steady) & (i >= 1) & (i < tf.size - 1) & (k >= 0)
                     & (k < tf.size))
            idx = np.flatnonzero(inner)
            lo_i, hi_i = np.minimum(i[idx] - 1, k[idx]), np.maximum(i[idx], k[idx])
            idx = idx[[bool(np.all(known[a:b + 1])) for a, b in zip(lo_i, hi_i)]]
            if idx.size < POOL_MIN_EDGES:
                continue
            r = float(np.median(np.abs(gaps[k[idx], j]))) / (n_span * step)  # 0 at the edge
            if not (math.isfinite(r) and r > 0):
                continue
            sigma = sig_h / r
            # phase: time less whole periods since the first
            y = t[idx] - t[idx[0]]
            y = y - period_j * np.round(y / period_j)
            centre = float(np.median(y))
            spread = robust_sigma(y, centre)
            tau2 = max(spread ** 2 - sigma ** 2, POOL_MIN_SCATTER_S ** 2)
            shrink = sigma ** 2 / (sigma ** 2 + tau2)
            for m, ym in zip(idx, y):
                if abs(ym - centre) > POOL_MAX_SIGMAS * sigma:
                    continue
                tn = t[m] + shrink * (centre - ym)
                if abs(tn - t[m]) > POOL_MAX_MOVE_S:
                    continue
                lo_b = iv[m, 0] if col == 1 else (iv[m - 1, 1] if m > 0 else -math.inf)
                hi_b = iv[m, 1] if col == 0 else (iv[m + 1, 0] if m + 1 < iv.shape[0]
                                                  else math.inf)
                if lo_b < tn < hi_b:
                    moved.append(abs(tn - iv[m, col]))
                    iv[m, col] = tn
    if info is not None:
        info['pooled_edges'] = len(moved)
        info['pooled_moved_over_1ms'] = int(np.sum(np.array(moved) > 1e-3))
        info['pooled_max_move_s'] = float(max(moved, default=0.0))


def _rearmed(iv: FloatArray, tf: FloatArray, gap: FloatArray, known: NDArray[np.bool_],
             rearm_m: float) -> FloatArray:
    """Drop contacts that begin before the leg cleared the ground by ``rearm_m`` since the
    last kept lift-off (unknown stretches in between count as cleared)."""
    if rearm_m <= 0 or iv.shape[0] < 2:
        return iv
    keep = [0]
    for k in range(1, iv.shape[0]):
        a, b = np.searchsorted(tf, [iv[keep[-1], 1], iv[k, 0]])
        seg = slice(a, max(b, a + 1))
        if (not np.all(known[seg])) or float(np.max(gap[seg], initial=-np.inf)) > rearm_m:
            keep.append(k)
    return iv[keep]


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


def single_support(contacts: dict[str, FloatArray], tripods: dict[str, tuple[str, ...]],
                   unknown: ArrayLike | None = None, *, guard_s: float = 1e-3,
                   dropped: list[tuple[str, float, float]] | None = None
                   ) -> dict[str, FloatArray]:
    """Per tripod, the intervals where any of its legs is in contact and no leg of the others.

    Returns ``{tripod: (k, 2)}`` [s], the longest piece of each tripod contact interval;
    pieces within ``guard_s`` of an ``unknown`` interval (:func:`leg_contacts`) are dropped
    (the other tripod's contact there is not known) and, when ``dropped`` is a list, appended
    to it as ``(tripod, start, end)``.
    """
    unk = np.zeros((0, 2)) if unknown is None else np.asarray(unknown, dtype=float).reshape(-1, 2)
    on = {tp: _union([contacts[leg] for leg in legs if leg in contacts])
          for tp, legs in tripods.items()}
    out: dict[str, FloatArray] = {}
    for tp, iv in on.items():
        others = _union([v for k, v in on.items() if k != tp])
        pieces = []
        for a, b in iv:
            longest = longest_free_segment(a, b, others)
            if longest is not None:
                s0, s1 = longest
                if not np.any((unk[:, 0] <= s1 + guard_s) & (unk[:, 1] >= s0 - guard_s)):
                    pieces.append((s0, s1))
                elif dropped is not None:
                    dropped.append((tp, float(s0), float(s1)))
        out[tp] = np.array(pieces, dtype=float).reshape(-1, 2)
    return out
