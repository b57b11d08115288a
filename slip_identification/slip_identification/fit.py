"""Per-stance SLIP fits: the SLIP-measure of Komsuoglu et al. (Eqs. 2-4) and a position fit.

Two estimators, reported side by side:

:class:`SlipFitter` (the paper's)
    The model trajectory starts from the stance's first measured state (spline-derived
    position and velocity) and ``nerr`` (Eq. 2) is minimised by Nelder-Mead on normalised
    parameters from ``(2000 N/m, 0.15 m, middle of the stance's x range)``; ``k, l0 > 0``.
    ``method='fast'`` runs one Nelder-Mead per stance *in lock step over the whole batch*
    (same algorithm, coefficients, initial simplex and stopping rule as
    ``scipy.optimize.minimize(method='Nelder-Mead')``), each step integrating every stance that
    needs a function value in one vectorised RK4 call; ``method='reference'`` runs
    ``scipy.optimize.minimize`` stance by stance on ``solve_ivp`` (rtol 1e-10) trajectories.

:class:`SlipPositionFitter`
    Fits the *measured positions* (raw motion-capture samples when the stance has them) by
    least squares with the initial position and velocity free, so noise in the
    spline-derived initial state does not bias the parameters.

Standard errors (both): the Gauss-Newton approximation ``cov = s^2 (J^T J)^-1`` of the
residual sum of squares at the optimum, ``s^2 = RSS / (n - p)``. For the paper's estimator the
residuals are the 1 kHz state errors, which are correlated (they are interpolated from ~120 Hz
samples), so ``cov`` is multiplied by ``N / n_raw`` (resampled over raw samples in the stance),
and the noise of the fixed initial state, estimated from the raw samples and carried through
the spline (:func:`first_state_cov`), is carried to the parameters (:func:`_initial_state_cov`).

Normalised parameters: ``q = (k / 2000, l0 / 0.15, 1 + (fx - fx0) / 0.15, 1 + c / 10,
1 + tau / 1)``, so the scipy initial simplex (5 % of each coordinate) is 100 N/m, 7.5 mm,
7.5 mm, 0.5 N s/m, 0.05 N m.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares, minimize

from . import _kernels
from .errors import NotFittedError, SlipDataError, StanceRejectedError
from .model import EXTENSIONS, SlipModel

try:
    from typing import Self
except ImportError:  # pragma: no cover - Python < 3.11
    from typing_extensions import Self

__all__ = [
    'K0_NPM',
    'L0_M',
    'MIN_STANCE_SAMPLES',
    'Stance',
    'SlipFitResult',
    'SlipFitter',
    'SlipPositionFitter',
    'FORCE_SWING_MIN',
    'first_state_cov',
    'first_state_covs',
    'nerr',
    'nerr_denominator',
    'nerr_noise_floor',
    'other_minimum',
    'raw_noise_m',
    'spring_force_swing',
    'stance_starts',
    'validate_stance',
]

FloatArray = NDArray[np.float64]
K0_NPM = 2000.0
L0_M = 0.15
MIN_STANCE_SAMPLES = 10  # at 1 kHz: 10 ms; raw mocap samples below 4 are refused too
MIN_RAW_SAMPLES = 4


@dataclass(frozen=True, eq=False)
class Stance:
    """One single-tripod stance in the sagittal world frame.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Uniformly spaced sample times [s] (1 kHz after preprocessing).
    state : ndarray, shape (N, 4)
        Measured ``[bx, bx', bz, bz']`` [m, m/s, m, m/s].
    tripod : str
        ``'left'`` or ``'right'`` (free text for synthetic data).
    raw_t_s : ndarray, shape (n,), optional
        Times of the raw motion-capture samples inside the stance [s].
    raw_xz_m : ndarray, shape (n, 2), optional
        Raw ``[bx, bz]`` at ``raw_t_s`` (world frame) [m].
    label : str
        Free identifier carried to the result (bag, run, index).
    """

    t_s: FloatArray
    state: FloatArray
    tripod: str = ''
    raw_t_s: FloatArray | None = None
    raw_xz_m: FloatArray | None = None
    label: str = ''

    @property
    def n_samples(self) -> int:
        return int(np.shape(self.t_s)[0])

    @property
    def dt_s(self) -> float:
        return float((self.t_s[-1] - self.t_s[0]) / (self.n_samples - 1))

    @property
    def n_raw(self) -> int:
        """Number of independent samples (raw mocap samples, else N)."""
        return self.n_samples if self.raw_t_s is None else int(np.shape(self.raw_t_s)[0])

    @property
    def touchdown_s(self) -> float:
        return float(self.t_s[0])

    @property
    def liftoff_s(self) -> float:
        return float(self.t_s[-1])


def validate_stance(stance: Stance, *, min_samples: int = MIN_STANCE_SAMPLES) -> None:
    """Raise :class:`StanceRejectedError` with a reason tag if the stance cannot be fitted."""
    t = np.asarray(stance.t_s, dtype=float)
    x = np.asarray(stance.state, dtype=float)
    if t.ndim != 1 or x.shape != (t.size, 4):
        raise StanceRejectedError(
            'bad_shape', f'stance {stance.label!r}: t_s (N,) and state (N, 4) expected, got '
            f'{t.shape} and {x.shape}')
    if t.size < min_samples:
        raise StanceRejectedError(
            'too_short', f'stance {stance.label!r} has {t.size} samples, need >= {min_samples}')
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x))):
        raise StanceRejectedError('nan', f'stance {stance.label!r} contains NaN or inf')
    dt = np.diff(t)
    if np.any(dt <= 0) or np.ptp(dt) > 1e-6 * max(float(np.mean(dt)), 1e-12) + 1e-9:
        raise StanceRejectedError(
            'non_uniform', f'stance {stance.label!r}: t_s must be increasing and uniform')
    if stance.raw_t_s is not None:
        if stance.raw_xz_m is None or np.shape(stance.raw_xz_m) != (np.size(stance.raw_t_s), 2):
            raise StanceRejectedError(
                'bad_shape', f'stance {stance.label!r}: raw_xz_m must be (n, 2) like raw_t_s')
        if np.size(stance.raw_t_s) < MIN_RAW_SAMPLES:
            raise StanceRejectedError(
                'too_short', f'stance {stance.label!r} has {np.size(stance.raw_t_s)} raw mocap '
                f'samples, need >= {MIN_RAW_SAMPLES}')
        if not np.all(np.isfinite(stance.raw_xz_m)):
            raise StanceRejectedError('nan', f'stance {stance.label!r}: raw mocap has NaN')


def nerr(model_state: ArrayLike, measured_state: ArrayLike) -> float:
    """Normalised state error of Eq. 2, the stance's fore/aft position taken from its first
    sample (:func:`nerr_denominator`).

    Parameters
    ----------
    model_state, measured_state : array_like, shape (N, 4), ``(bx, bx', bz, bz')``

    Returns
    -------
    float
        ``sum_i ||x^m_i - x^e_i|| / sum_i ||x^e_i - (bx^e_1, 0, 0, 0)||`` (inf if the model
        is not finite).
    """
    xm = np.asarray(model_state, dtype=float)
    xe = np.asarray(measured_state, dtype=float)
    num = float(np.sum(np.sqrt(np.sum((xm - xe) ** 2, axis=1))))
    return num / nerr_denominator(xe) if math.isfinite(num) else math.inf


def nerr_denominator(measured_state: ArrayLike, *, origin: str = 'stance') -> float:
    """Eq. 2's normaliser ``sum_i ||x^e_i||`` of a stance's measured states (N, 4)
    ``(bx, bx', bz, bz')``.

    ``origin='stance'`` (what nerr uses): ``bx`` from the stance's first sample, so that
    the SLIP-measure does not depend on where the world frame's origin lies (the paper
    constrains the foot hold to ``fx > 0``, ahead of the touchdown position; with the run's
    origin a noise-free steady run's stances read nerr 0.0205 near it and 0.0066 two metres
    on: an outside review). ``'world'``: ``bx`` as measured, Eq. 2 read literally."""
    xe = np.asarray(measured_state, dtype=float)
    if origin == 'stance' and xe.size:
        xe = xe.copy()
        xe[:, 0] -= xe[0, 0]
    elif origin not in ('stance', 'world'):
        raise ValueError(f"origin must be 'stance' or 'world', got {origin!r}")
    return float(np.sum(np.sqrt(np.sum(xe**2, axis=1))))


@dataclass(frozen=True)
class SlipFitResult:
    """Fit of one stance.

    ``params``/``stderr`` map :attr:`SlipModel.param_names` to values in SI units
    (``stiffness`` N/m, ``rest_length`` m, ``foot_x`` m, ``leg_damping`` N s/m,
    ``hip_torque`` N m); :class:`SlipPositionFitter` adds ``bx0, vx0, bz0, vz0``.
    """

    model: str
    estimator: str
    params: dict[str, float]
    stderr: dict[str, float]
    nerr: float
    converged: bool
    iterations: int
    evaluations: int
    samples: int
    touchdown_s: float
    liftoff_s: float
    tripod: str = ''
    label: str = ''
    rss: float = math.nan
    extra: dict[str, float] = field(default_factory=dict)
    #: the Nelder-Mead start kept (:func:`stance_starts`): 'paper', 'stance1', ...
    start: str = 'paper'
    #: range of the fitted spring force over the stance over its mean
    #: (:func:`spring_force_swing`); under :data:`FORCE_SWING_MIN` k and l0 are not
    #: identified apart
    force_swing: float = math.nan
    #: the lowest converged other start's result when it is another minimum (k apart by more
    #: than :data:`OTHER_MINIMUM_K_RATIO` or l0 by :data:`OTHER_MINIMUM_L0_RATIO`):
    #: parameters, ``nerr``, ``force_swing`` and ``start``; empty when every start found
    #: this one (:func:`other_minimum`)
    other_minimum: dict[str, Any] = field(default_factory=dict)
    #: the nerr that the motion capture's white noise alone gives this stance through the
    #: spline's states (:func:`nerr_noise_floor`); NaN when the noise is not known
    nerr_noise_floor: float = math.nan
    #: Eq. 2 read literally: normalised by the states with ``bx`` in the world frame (the
    #: paper's Table 3 measure; it depends on where the frame's origin lies, so ``nerr``
    #: takes ``bx`` from the stance's first sample: :func:`nerr_denominator`)
    nerr_world: float = math.nan

    @property
    def stiffness_npm(self) -> float:
        return self.params['stiffness']

    @property
    def rest_length_m(self) -> float:
        return self.params['rest_length']

    @property
    def foot_x_m(self) -> float:
        return self.params['foot_x']

    def bic(self) -> float:
        """Bayesian information criterion from the residual sum of squares (Gaussian)."""
        n = self.samples
        k = len(self.params)
        if not (self.rss > 0 and n > k):
            return math.nan
        return n * math.log(self.rss / n) + k * math.log(n)


# ---------------------------------------------------------------------------- normalisation
def _scales(model: SlipModel) -> FloatArray:
    return np.array([K0_NPM, L0_M, L0_M] + [EXTENSIONS[e][1] for e in model.extensions])


def _to_physical(q: FloatArray, fx0: FloatArray, model: SlipModel,
                 scales: FloatArray | None = None) -> FloatArray:
    """(M, P) normalised -> physical; ``fx0`` (M,); ``scales`` (M, P) per row (a start other
    than the paper's: its k and l0 in the first two) or the paper's."""
    s = np.broadcast_to(_scales(model) if scales is None else scales, q.shape)
    p = (q - 1.0) * s
    p[:, 0] = q[:, 0] * s[:, 0]
    p[:, 1] = q[:, 1] * s[:, 1]
    p[:, 2] += fx0
    return p


def _to_normalised(p: FloatArray, fx0: FloatArray, model: SlipModel) -> FloatArray:
    s = _scales(model)
    q = p / s + 1.0
    q[:, 0] = p[:, 0] / s[0]
    q[:, 1] = p[:, 1] / s[1]
    q[:, 2] = (p[:, 2] - fx0) / s[2] + 1.0
    return q


def _ext_index(model: SlipModel) -> NDArray[np.int64]:
    """Positions of (leg_damping, hip_torque) in the parameter vector, -1 if absent."""
    names = model.param_names
    return np.array([names.index(e) if e in names else -1
                     for e in ('leg_damping', 'hip_torque')], dtype=np.int64)


def _physical5(p: FloatArray, model: SlipModel) -> FloatArray:
    """(M, P) model parameters -> (M, 5) ``k, l0, fx, c, tau`` for the kernels."""
    out = np.zeros((p.shape[0], 5))
    out[:, :3] = p[:, :3]
    for e, j in enumerate(_ext_index(model)):
        if j >= 0:
            out[:, 3 + e] = p[:, j]
    return np.ascontiguousarray(out)


# ---------------------------------------------------------------------------- batched NM
class _Batch:
    """Stances of one length bucket, padded to the longest, state arrays (N, 4, B)."""

    def __init__(self, model: SlipModel, stances: Sequence[Stance], stride: int) -> None:
        self.model = model
        self.stride = stride
        self.n = max(s.n_samples for s in stances)
        self.dt_s = float(np.median([s.dt_s for s in stances]))
        b = len(stances)
        self.xe = np.zeros((self.n, 4, b))
        self.mask = np.zeros((self.n, b), dtype=bool)
        for j, s in enumerate(stances):
            self.xe[: s.n_samples, :, j] = s.state
            self.mask[: s.n_samples, j] = True
        self.x0 = self.xe[0].T.copy()  # (B, 4)
        norms = np.sqrt(np.sum(self.xe**2, axis=1))
        self.den = np.sum(np.where(self.mask, norms, 0.0), axis=0)
        self.fx0 = np.array([0.5 * (s.state[:, 0].min() + s.state[:, 0].max()) for s in stances])
        self.n_raw = np.array([s.n_raw for s in stances])
        self.stances = stances

    def nerr(self, q: FloatArray, idx: NDArray[np.intp],
             scales: FloatArray | None = None) -> FloatArray:
        """nerr of normalised parameter rows ``q`` (M, P) for stances ``idx`` (M,), each
        row's ``scales`` (M, P) given or the paper's."""
        out = np.full(idx.size, np.inf)
        ok = (q[:, 0] > 0) & (q[:, 1] > 0) & np.all(np.isfinite(q), axis=1)
        if not ok.any():
            return out
        idx_ok = idx[ok]
        p = _to_physical(q[ok], self.fx0[idx_ok], self.model,
                         None if scales is None else scales[ok])
        traj = self.model.simulate_batch(self.x0[idx_ok], p, self.n, self.dt_s,
                                         stride=self.stride)
        with np.errstate(all='ignore'):
            traj -= self.xe[:, :, idx_ok]
            traj *= traj
            err = np.sqrt(traj.sum(axis=1))
            err = np.where(self.mask[:, idx_ok], err, 0.0).sum(axis=0) / self.den[idx_ok]
        out[ok] = np.where(np.isfinite(err), err, np.inf)
        return out


def _batched_nelder_mead(f: Callable[[FloatArray, NDArray[np.intp]], FloatArray], b: int,
                         n_params: int, *, xatol: float, fatol: float, maxiter: int
                         ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.int_],
                                    NDArray[np.int_]]:
    """Nelder-Mead as in scipy (rho 1, chi 2, psi 0.5, sigma 0.5), one simplex per stance.

    Returns the best vertex (B, P), its value (B,), converged (B,), iterations and
    function evaluations per stance.
    """
    p = n_params
    x0 = np.ones(p)
    sim = np.empty((b, p + 1, p))
    sim[:] = x0
    for k in range(p):
        sim[:, k + 1, k] *= 1.05
    all_idx = np.repeat(np.arange(b), p + 1)
    fsim = f(sim.reshape(-1, p), all_idx).reshape(b, p + 1)
    order = np.argsort(fsim, axis=1)
    sim = np.take_along_axis(sim, order[:, :, None], axis=1)
    fsim = np.take_along_axis(fsim, order, axis=1)
    iterations = np.ones(b, dtype=int)
    fcalls = np.full(b, p + 1)
    converged = np.zeros(b, dtype=bool)
    active = np.ones(b, dtype=bool)
    maxfun = maxiter
    while True:
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        s, fs = sim[idx], fsim[idx]
        with np.errstate(invalid='ignore'):
            done = ((np.max(np.abs(s[:, 1:] - s[:, :1]), axis=(1, 2)) <= xatol)
                    & (np.max(np.abs(fs[:, :1] - fs[:, 1:]), axis=1) <= fatol))
        converged[idx[done]] = True
        stop = done | (iterations[idx] >= maxiter) | (fcalls[idx] >= maxfun)
        active[idx[stop]] = False
        keep = ~stop
        idx, s, fs = idx[keep], s[keep], fs[keep]
        if idx.size == 0:
            break
        xbar = s[:, :-1].mean(axis=1)
        worst = s[:, -1]
        xr = 2.0 * xbar - worst
        fxr = f(xr, idx)
        fcalls[idx] += 1
        expand = fxr < fs[:, 0]
        accept = ~expand & (fxr < fs[:, -2])
        outside = ~expand & ~accept & (fxr < fs[:, -1])
        inside = ~expand & ~accept & ~outside
        second = ~accept
        x2 = np.where(expand[:, None], 3.0 * xbar - 2.0 * worst,
                      np.where(outside[:, None], 1.5 * xbar - 0.5 * worst,
                               0.5 * xbar + 0.5 * worst))
        f2 = np.full(idx.size, np.inf)
        if second.any():
            f2[second] = f(x2[second], idx[second])
            fcalls[idx[second]] += 1
        new_x = xr.copy()
        new_f = fxr.copy()
        take2 = (expand & (f2 < fxr)) | (outside & (f2 <= fxr)) | (inside & (f2 < fs[:, -1]))
        new_x[take2] = x2[take2]
        new_f[take2] = f2[take2]
        shrink = (outside & ~(f2 <= fxr)) | (inside & ~(f2 < fs[:, -1]))
        replace = ~shrink
        s[replace, -1] = new_x[replace]
        fs[replace, -1] = new_f[replace]
        if shrink.any():
            sh = np.flatnonzero(shrink)
            s[sh, 1:] = s[sh, :1] + 0.5 * (s[sh, 1:] - s[sh, :1])
            pts = s[sh, 1:].reshape(-1, p)
            fs[sh, 1:] = f(pts, np.repeat(idx[sh], p)).reshape(sh.size, p)
            fcalls[idx[sh]] += p
        iterations[idx] += 1
        order = np.argsort(fs, axis=1)
        sim[idx] = np.take_along_axis(s, order[:, :, None], axis=1)
        fsim[idx] = np.take_along_axis(fs, order, axis=1)
    return sim[:, 0].copy(), fsim[:, 0].copy(), converged, iterations, fcalls


def _stderr_from_jacobian(jac: FloatArray, rss: float, n_res: int, inflation: float
                          ) -> FloatArray:
    """Standard errors from ``s^2 (J^T J)^-1``; NaN where J^T J is singular or dof <= 0."""
    p = jac.shape[1]
    dof = n_res - p
    if dof <= 0 or not np.all(np.isfinite(jac)):
        return np.full(p, np.nan)
    jtj = jac.T @ jac
    try:
        cov = np.linalg.inv(jtj) * (rss / dof) * inflation
    except np.linalg.LinAlgError:
        return np.full(p, np.nan)
    d = np.diag(cov)
    return np.where(d >= 0, np.sqrt(np.abs(d)), np.nan)


#: steps (m, m/s, m, m/s) of the central differences in the initial state
#: (:func:`_initial_state_cov`): absolute, so that the standard errors do not depend on where
#: the world origin is (steps relative to bx0 moved k's by 20 % 2 km away; an outside review)
_X0_STEP = np.array([1e-5, 1e-4, 1e-5, 1e-4])


def _param_steps(p: FloatArray, model: SlipModel) -> FloatArray:
    """Central-difference steps of the parameters (rows or one row): 1e-4 relative (at least
    1e-5 of the scale), foot_x's from its scale alone (a world x, not a magnitude)."""
    sc = _scales(model)
    steps = np.maximum(np.abs(p) * 1e-4, sc * 1e-5)
    steps[..., 2] = sc[2] * 1e-4
    return steps


#: third differences of white noise: the sum of squares of their weights (1, -3, 3, -1)
_D3_WEIGHT = 20.0
#: the median of a chi-square variable with one degree of freedom
_CHI2_1_MEDIAN = 0.454936
#: raw samples a stance needs for its own noise estimate (four third differences)
_NOISE_MIN_RAW = 7


def raw_noise_m(raw_xz_m: ArrayLike) -> FloatArray:
    """White-noise standard deviation of motion-capture positions ``(n, 2)`` [m], per axis,
    from their third differences (robust: their median square); NaN under
    :data:`_NOISE_MIN_RAW` samples. The motion's own third difference (jerk times dt^3)
    is small against the noise at mocap rates: on simulated EduBot stances with 0.2 mm
    noise at 120 Hz it reads 0.20-0.24 mm (running's vertical 0.32 mm, the touchdown's
    jerk)."""
    r = np.asarray(raw_xz_m, dtype=float).reshape(-1, 2)
    if r.shape[0] < _NOISE_MIN_RAW:
        return np.full(2, np.nan)
    d = np.diff(r, n=3, axis=0)
    return np.sqrt(np.median(d**2, axis=0) / _CHI2_1_MEDIAN / _D3_WEIGHT)


@functools.lru_cache(maxsize=1024)
def _spline_noise_gains(phase_milli: int) -> tuple[float, float, float]:
    """Variance gains of an interpolating cubic spline's value and slope at ``phase`` (in
    thousandths of a sample interval after a sample) for white noise of unit variance on a
    long uniform grid of unit spacing: ``(sum w^2, sum w'^2, sum w w')``. The 1 kHz states
    are such a spline's value and slope (:func:`.preprocess.sagittal_state`)."""
    n = 41
    cs = CubicSpline(np.arange(n, dtype=float), np.eye(n))
    t = (n - 1) // 2 + phase_milli / 1000.0
    w, wd = cs(t), cs(t, 1)
    return float(w @ w), float(wd @ wd), float(w @ wd)


def _raw(stance: Stance) -> tuple[FloatArray, FloatArray]:
    """The stance's raw sample times and (x, z) positions (its own grid without them)."""
    if stance.raw_t_s is not None and stance.raw_xz_m is not None:
        return (np.asarray(stance.raw_t_s, dtype=float),
                np.asarray(stance.raw_xz_m, dtype=float))
    return np.asarray(stance.t_s, dtype=float), np.asarray(stance.state, dtype=float)[:, [0, 2]]


@functools.lru_cache(maxsize=1)
def _mean_spline_noise_gains() -> tuple[float, float]:
    """:func:`_spline_noise_gains`' value and slope variance gains averaged over the phase
    between two samples (the 1 kHz states fall at every phase)."""
    g = np.array([_spline_noise_gains(k)[:2] for k in range(0, 1000, 25)])
    return float(np.mean(g[:, 0])), float(np.mean(g[:, 1]))


def nerr_noise_floor(stance: Stance, sigma_m: ArrayLike | None = None) -> float:
    """The nerr (Eq. 2, :func:`nerr`) that white motion-capture noise alone gives a stance: the
    expected norm of the noise each spline state carries (positions ``sigma``, velocities
    ``sigma / dt`` times the spline's slope gain), over the stance's normaliser. The
    velocities dominate and grow with the rate: 0.2 mm at 500 Hz puts about 0.13 m/s on
    them, at 120 Hz 0.03 m/s (an outside review: EduBot running read nerr 0.160 at 500 Hz
    against 0.043 at 120 Hz and 0.011 without noise). ``sigma_m`` per axis, by default
    :func:`raw_noise_m` of the stance's raw samples; NaN when it is not known. It reads high
    at low rates, where the motion's own third differences enter the noise estimate
    (simulated EduBot running, 0.2 mm: at 500 Hz 0.19 for a measured nerr of 0.23, 0.015
    without noise; at 100 Hz 0.084 for 0.051)."""
    rt, rxz = _raw(stance)
    sigma = raw_noise_m(rxz) if sigma_m is None else np.asarray(sigma_m, dtype=float)
    steps = np.diff(rt)
    steps = steps[steps > 0]
    if steps.size == 0 or not np.all(np.isfinite(sigma)) or \
            stance.raw_t_s is None or stance.raw_xz_m is None:
        return math.nan
    dt = float(np.median(steps))
    cp, cv = _mean_spline_noise_gains()
    # E||n|| of the state noise, dominated by its two velocities (a Rayleigh norm:
    # sqrt(pi / 4) of its root mean square)
    per_state = math.sqrt(math.pi / 4.0 * float(np.sum(sigma**2)) * (cp + cv / dt**2))
    den = nerr_denominator(stance.state)
    return per_state * int(stance.n_samples) / den if den > 0 else math.nan


def first_state_cov(stance: Stance, sigma_m: ArrayLike | None = None) -> FloatArray:
    """Covariance (4, 4) of the noise of a stance's first state ``(bx, vx, bz, vz)``.

    The 1 kHz states are a cubic spline through the raw motion-capture samples; its value
    and slope at the first state's time carry the raw samples' white noise (``sigma_m`` per
    axis, by default estimated from their third differences, :func:`raw_noise_m`) through
    the spline's weights at that phase between two samples. A stance without raw samples is
    taken as sampled on its own grid. NaN when the noise is not known (too few raw samples
    for the estimate)."""
    rt, rxz = _raw(stance)
    sigma = raw_noise_m(rxz) if sigma_m is None else np.asarray(sigma_m, dtype=float)
    steps = np.diff(rt)
    steps = steps[steps > 0]         # repeated raw times carry no spacing
    if steps.size == 0 or not np.all(np.isfinite(sigma)):
        return np.full((4, 4), np.nan)
    dt = float(np.median(steps))
    # the first state lies this far past the raw sample before it (in sample intervals)
    phase = (1.0 - (rt[0] - float(stance.t_s[0])) / dt) % 1.0
    cp, cv, cpv = _spline_noise_gains(int(round(1000 * phase)) % 1000)
    cov = np.zeros((4, 4))
    for k, sg in zip((0, 2), sigma):
        cov[k, k] = cp * sg**2
        cov[k + 1, k + 1] = cv * (sg / dt) ** 2
        cov[k, k + 1] = cov[k + 1, k] = cpv * sg**2 / dt
    return cov


def first_state_covs(stances: Sequence[Stance], residual_ms: FloatArray) -> FloatArray:
    """(B, 4, 4) first-state noise covariances of stances fitted together
    (:func:`first_state_cov`). A stance with too few raw samples for its own noise estimate
    (under :data:`_NOISE_MIN_RAW`: a short stance at a low mocap rate) takes the median
    estimate of the others (one motion capture); alone, or without raw samples at all (its
    states are then the measurement), the diagonal of its residuals' mean squares
    ``residual_ms`` (B, 4) per state component, which also holds model misfit and the drift
    from the first state's own error, so it errs large."""
    # a stance without raw samples: its states are the measurement, a spline's smooth
    # output whose third differences say nothing of the noise (0.8 um read for 0.2 mm: the
    # standard errors 10-16 times too small; an outside review): its residuals stand in
    has_raw = np.array([s.raw_t_s is not None and s.raw_xz_m is not None for s in stances])
    sig = np.array([raw_noise_m(_raw(s)[1]) if r else (np.nan, np.nan)
                    for s, r in zip(stances, has_raw)]).reshape(-1, 2)
    known = np.all(np.isfinite(sig), axis=1)
    pooled = np.median(sig[known], axis=0) if known.any() else None
    out = np.empty((len(stances), 4, 4))
    for j, s in enumerate(stances):
        cov = np.full((4, 4), np.nan)
        if has_raw[j] and (known[j] or pooled is not None):
            cov = first_state_cov(s, sig[j] if known[j] else pooled)
        out[j] = cov if np.all(np.isfinite(cov)) else np.diag(residual_ms[j])
    return out


def _initial_state_cov(jac_p: FloatArray, jac_x: FloatArray, s_x: FloatArray) -> FloatArray:
    """The parameters' covariance carried from the fixed initial state, ``G S_x G^T``.

    The paper's estimator starts the model from the stance's first measured state, which
    carries the same noise as every other sample, and does not fit it: the parameters then
    move with it, ``G = dp*/dx0 = -(Jp^T Jp)^-1 Jp^T Jx`` (Gauss-Newton, ``Jx`` the residuals'
    Jacobian in the initial state; this linear prediction explained 98-99 % of the estimates'
    error in an outside review). ``S_x`` is the first state's noise covariance
    (:func:`first_state_covs`). Left out, the standard errors of spline-derived stances
    were 1.4-15 times smaller than the scatter of the estimates.

    ``jac_p`` (R, P) and ``jac_x`` (R, 4) over the same residual rows, ``s_x`` (4, 4)."""
    jtj = jac_p.T @ jac_p
    g = -np.linalg.solve(jtj, jac_p.T @ jac_x)
    return g @ s_x @ g.T


def _bucket(stances: Sequence[Stance], max_batch: int, spread: float) -> list[list[int]]:
    """Group stance indices by sample spacing (one integration step per batch: stances of
    other spacings were integrated with the group's median, 1 kHz and 2 ms stances fitted
    together gave k 5400 for 12000, converged) and then by similar length (padding waste <=
    ``spread``)."""
    def spacing(i: int) -> float:   # 6 significant digits: rounding noise is one spacing
        return float(f'{stances[i].dt_s:.6g}')

    order = sorted(range(len(stances)), key=lambda i: (spacing(i), stances[i].n_samples))
    groups: list[list[int]] = []
    for i in order:
        n = stances[i].n_samples
        if groups and len(groups[-1]) < max_batch and spacing(i) == spacing(groups[-1][0]) \
                and n <= (1.0 + spread) * stances[groups[-1][0]].n_samples:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


#: a fit whose spring force varies less than this over the stance (range over mean) is a
#: nearly constant leg force: k and l0 are not identified apart (:func:`spring_force_swing`)
FORCE_SWING_MIN = 1.0


def spring_force_swing(stance: Stance, params: dict[str, float]) -> float:
    """Range of the fitted spring force ``k (l0 - l(t))`` over the stance, over its mean
    magnitude (``l`` the measured body-to-foot distance).

    A bouncing leg that touches down near its rest length swings from about zero to twice its
    mean: 2.6-3.5 on simulated EduBot running and jogging stances. The lowest nerr of a walk
    or a pace stance lies along ``k (l0 - l) = about m g`` (a soft spring far longer than the
    leg): swing 0.01-0.4, so k and l0 there are not identified apart, only their product; the
    paper's single start sat elsewhere on that valley. Below :data:`FORCE_SWING_MIN` a result
    is flagged so."""
    x = np.asarray(stance.state, dtype=float)
    leg = np.hypot(x[:, 0] - params['foot_x'], x[:, 2])
    force = params['stiffness'] * (params['rest_length'] - leg)
    mean = float(np.mean(np.abs(force)))
    return float(np.ptp(force) / mean) if mean > 0 else math.nan


#: another start's result is another minimum when its k is this many times apart ...
OTHER_MINIMUM_K_RATIO = 1.5
#: ... or its l0 this many times
OTHER_MINIMUM_L0_RATIO = 1.1
#: a stance whose other minimum's nerr is within this factor of the kept one's has two
#: minima that the data hardly tell apart (``gaits[].two_minima_stances``)
TWO_MINIMA_NERR_RATIO = 1.1


def other_minimum(kept: int, params: FloatArray, nerrs: FloatArray,
                  converged: NDArray[np.bool_]) -> int | None:
    """Index of the lowest-nerr converged start whose result is another minimum than the
    kept start's (k apart by more than :data:`OTHER_MINIMUM_K_RATIO` or l0 by
    :data:`OTHER_MINIMUM_L0_RATIO`), or None.

    On a walk or pace stance the starts end in two minima: a bounce (k about 3,500 N/m,
    force_swing 3-4) and the constant-force valley (k 250-600 N/m, force_swing under 0.5),
    their nerr within 10-25 % of each other (simulated EduBot). Motion-capture noise moves a
    stance from one to the other (an outside review: pace k 158 noise-free, 3,433 +- 664
    noisy), which no local standard error covers: the other minimum is reported beside the
    kept one."""
    k0, l0 = params[kept, 0], params[kept, 1]
    best = None
    for i in range(len(nerrs)):
        if i == kept or not converged[i] or not np.isfinite(nerrs[i]):
            continue
        k_ratio = max(params[i, 0], k0) / max(min(params[i, 0], k0), 1e-300)
        l_ratio = max(params[i, 1], l0) / max(min(params[i, 1], l0), 1e-300)
        if (k_ratio > OTHER_MINIMUM_K_RATIO or l_ratio > OTHER_MINIMUM_L0_RATIO) and (
                best is None or nerrs[i] < nerrs[best]):
            best = i
    return best


#: the starts of :class:`SlipFitter` ``starts='multi'`` besides the paper's: (stiffness factor
#: on ``m (pi / T_stance)^2``, rest-length factor on the touchdown leg length)
STANCE_STARTS = ((1.0, 1.0), (3.0, 1.0))


def stance_starts(stance: Stance, model: SlipModel) -> list[tuple[str, float, float]]:
    """Nelder-Mead starts ``(name, k [N/m], l0 [m])`` for one stance: the paper's
    ``(2000 N/m, 0.15 m)`` first, then the stance's own scales (:data:`STANCE_STARTS`).

    The stance's scales: half a spring-mass oscillation in the stance's duration ``T``
    (``k = m (pi / T)^2``) and the leg length at touchdown (the first state's distance to the
    foot guess, the middle of the stance's x range, on the ground). They do not depend on the
    robot's size, as the paper's fixed guess (EduBot's) does. Starts that are not finite and
    positive are left out."""
    xe = np.asarray(stance.state, dtype=float)
    fx0 = 0.5 * (xe[:, 0].min() + xe[:, 0].max())
    leg = math.hypot(xe[0, 0] - fx0, xe[0, 2])
    dur = stance.liftoff_s - stance.touchdown_s
    k_t = model.mass_kg * (math.pi / dur) ** 2 if dur > 0 else math.nan
    out = [('paper', K0_NPM, L0_M)]
    for i, (fk, fl) in enumerate(STANCE_STARTS, start=1):
        k, l0 = fk * k_t, fl * leg
        if math.isfinite(k) and math.isfinite(l0) and k > 0 and l0 > 0:
            out.append((f'stance{i}', k, l0))
    return out


class SlipFitter:
    """The paper's SLIP-measure fit (Eqs. 2-4), one Nelder-Mead per stance and start.

    Parameters
    ----------
    model : SlipModel
        Template (mass, extensions).
    method : {'fast', 'reference'}
        Lock-step batched Nelder-Mead on vectorised RK4, or scipy on ``solve_ivp``.
    xatol, fatol : float
        Nelder-Mead stopping tolerances on the normalised parameters and on nerr.
    maxiter : int
        Iteration (and function evaluation) cap; a stance stopped by it has
        ``converged=False``.
    stride : int
        Samples per RK4 step in the fast path (Hermite output in between).
    stderr : bool
        Compute standard errors (costs 2P + 8 extra trajectories per stance).
    first_state_noise : bool
        Carry the noise of the fixed first state into the standard errors
        (:func:`first_state_cov`, :func:`_initial_state_cov`; default). False: the residual
        part alone, which on spline-derived stances is 3-40 times too small.
    max_batch : int
        Stances integrated together (memory ~ 8 * N * 4 * 4 * max_batch bytes).
    compiled : bool
        Use the numba kernels of :mod:`slip_identification._kernels` when numba is installed
        (one compiled Nelder-Mead per stance, stances in parallel); otherwise the lock-step
        numpy Nelder-Mead over the batch.
    starts : {'multi', 'paper'}
        ``'paper'``: one Nelder-Mead from the paper's ``(2000 N/m, 0.15 m)``. ``'multi'``
        (default): also from the stance's own scales (:func:`stance_starts`), keeping the
        lowest nerr; the paper's start's result is kept unless another is lower by more than
        ``fatol``, so where it found the minimum the fit is the paper's. The paper's single
        start stops in a local minimum on some stances: simulated EduBot running, 3 of 40
        stances at nerr 0.14-0.20 where 0.05 was there (k about 2000 N/m, the start, for
        7000); walks, most stances at k 2000-6000 N/m where nerr is 5-27 % lower near
        300-450 N/m (which the position fit, another objective, also finds). ``result.start``
        names the start kept. Costs one Nelder-Mead per start.

    Attributes
    ----------
    results_ : list of SlipFitResult
        One per stance, in input order.
    """

    def __init__(self, model: SlipModel | None = None, *,
                 method: Literal['fast', 'reference'] = 'fast', xatol: float = 1e-4,
                 fatol: float = 1e-6, maxiter: int = 1000, stride: int = 2,
                 stderr: bool = True, max_batch: int = 4096, compiled: bool = True,
                 starts: Literal['multi', 'paper'] = 'multi',
                 first_state_noise: bool = True) -> None:
        if method not in ('fast', 'reference'):
            raise SlipDataError(f"method must be 'fast' or 'reference', got {method!r}")
        if starts not in ('multi', 'paper'):
            raise SlipDataError(f"starts must be 'multi' or 'paper', got {starts!r}")
        self.starts = starts
        self.model = model if model is not None else SlipModel()
        self.method = method
        self.xatol = xatol
        self.fatol = fatol
        self.maxiter = maxiter
        self.stride = stride
        self.stderr = stderr
        self.first_state_noise = first_state_noise
        self.max_batch = max_batch
        self.compiled = compiled

    @property
    def results(self) -> list[SlipFitResult]:
        if not hasattr(self, 'results_'):
            raise NotFittedError('SlipFitter.results_ read before fit()')
        return self.results_

    def fit(self, stances: Sequence[Stance]) -> Self:
        """Fit every stance (each validated first; invalid ones raise StanceRejectedError)."""
        for s in stances:
            validate_stance(s)
        results: list[SlipFitResult | None] = [None] * len(stances)
        if self.method == 'reference':
            for i, s in enumerate(stances):
                results[i] = self._fit_reference(s)
        else:
            for group in _bucket(stances, self.max_batch, 0.25):
                for i, r in zip(group, self._fit_fast([stances[i] for i in group])):
                    results[i] = r
        self.results_ = [r for r in results if r is not None]
        return self

    # ------------------------------------------------------------------ fast path
    def _starts(self, s: Stance) -> list[tuple[str, float, float]]:
        starts = stance_starts(s, self.model)
        return starts[:1] if self.starts == 'paper' else starts

    def _pick(self, f: FloatArray, conv: NDArray[np.bool_] | None = None) -> int:
        """The start kept among values ``f`` (the paper's first): the lowest among the
        converged ones (all when none converged), the paper's unless another is lower by more
        than ``fatol``. (A start that ran along a walk's or a pace's constant-force valley
        without converging gave k and l0 that depend on ``maxiter``: l0 1.8 m at 1000
        iterations, 291 m at 10,000; an outside review.)"""
        fin = np.where(np.isfinite(f), f, np.inf)
        if conv is not None and np.any(conv):
            fin = np.where(conv, fin, np.inf)
        best = int(np.argmin(fin))
        return 0 if fin[0] <= fin[best] + self.fatol else best

    def _fit_fast(self, stances: Sequence[Stance]) -> list[SlipFitResult]:
        model = self.model
        batch = _Batch(model, stances, self.stride)
        starts = [self._starts(s) for s in stances]
        rows = np.array([j for j, st in enumerate(starts) for _ in st], dtype=np.intp)
        scales = np.repeat(_scales(model)[None, :], rows.size, axis=0)
        scales[:, :2] = [(k, l0) for st in starts for _, k, l0 in st]
        if _kernels.HAVE_NUMBA and self.compiled:
            q, f, conv, iters, calls = _kernels.fit_many(
                np.ascontiguousarray(batch.x0[rows]),
                np.ascontiguousarray(batch.xe.transpose(2, 0, 1)[rows]),
                batch.mask.sum(axis=0).astype(np.int64)[rows], batch.den[rows],
                batch.fx0[rows], batch.dt_s, self.stride, 1.0 / model.mass_kg,
                model.gravity_mps2, model.gravity_x_mps2, scales, _ext_index(model),
                model.n_params, self.xatol,
                self.fatol, self.maxiter)
        else:
            q, f, conv, iters, calls = _batched_nelder_mead(
                lambda qq, idx: batch.nerr(qq, rows[idx], scales[idx]), rows.size,
                model.n_params, xatol=self.xatol, fatol=self.fatol, maxiter=self.maxiter)
        p = _to_physical(q, batch.fx0[rows], model, scales)
        first = np.concatenate([[0], np.cumsum([len(st) for st in starts])[:-1]])
        # function evaluations per stance over all its starts (one pass, not one per stance)
        evaluations = np.bincount(rows, weights=calls, minlength=len(stances))
        pick = np.array([a + self._pick(f[a:a + len(st)], conv[a:a + len(st)])
                         for a, st in zip(first, starts)], dtype=np.intp)
        pbest, fbest = p[pick], f[pick]
        errs = self._stderr_batch(batch, pbest) if self.stderr else \
            (np.full(pbest.shape, np.nan), np.full(len(stances), np.nan))
        out = []
        for j, s in enumerate(stances):
            i = pick[j]
            a, m = first[j], len(starts[j])
            o = other_minimum(i - a, p[a:a + m], f[a:a + m], conv[a:a + m])
            alt = None if o is None else (p[a + o], float(f[a + o]), starts[j][o][0])
            out.append(self._result(s, pbest[j], errs[0][j], float(fbest[j]),
                                    bool(conv[i] and np.isfinite(fbest[j])), int(iters[i]),
                                    int(evaluations[j]), float(errs[1][j]),
                                    starts[j][i - first[j]][0], alt))
        return out

    def _stderr_batch(self, batch: _Batch, pbest: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Gauss-Newton standard errors and RSS of every stance of the bucket, vectorised."""
        model = self.model
        b, p = pbest.shape
        m = 2 * p + 9        # the optimum, +-each parameter, +-each initial state component
        steps = _param_steps(pbest, model)  # (B, P)
        xsteps = np.repeat(_X0_STEP[None, :], b, axis=0)  # (B, 4)
        pts = np.repeat(pbest[:, None, :], m, axis=1)  # (B, m, P)
        xs = np.repeat(batch.x0[:, None, :], m, axis=1)  # (B, m, 4)
        for k in range(p):
            pts[:, 1 + 2 * k, k] += steps[:, k]
            pts[:, 2 + 2 * k, k] -= steps[:, k]
        for k in range(4):
            xs[:, 2 * p + 1 + 2 * k, k] += xsteps[:, k]
            xs[:, 2 * p + 2 + 2 * k, k] -= xsteps[:, k]
        flat = pts.reshape(-1, p)
        x0 = xs.reshape(-1, 4)
        if _kernels.HAVE_NUMBA and self.compiled:
            traj = _kernels.trajectories(_physical5(flat, model), np.ascontiguousarray(x0),
                                         batch.n, batch.dt_s, self.stride,
                                         1.0 / model.mass_kg, model.gravity_mps2,
                                         model.gravity_x_mps2)
        else:
            traj = model.simulate_batch(x0, flat, batch.n, batch.dt_s,
                                        stride=self.stride).transpose(2, 0, 1)
        traj = traj.reshape(b, m, batch.n, 4)
        mask = batch.mask.T[:, :, None].copy()  # (B, N, 1)
        mask[:, 0] = False  # sample 0 is the fixed initial state
        xe = batch.xe.transpose(2, 0, 1)
        with np.errstate(all='ignore'):
            res0 = np.where(mask, traj[:, 0] - xe, 0.0)
            rss = np.sum(res0**2, axis=(1, 2))
            jac = np.empty((b, batch.n * 4, p))
            for k in range(p):
                d = (traj[:, 1 + 2 * k] - traj[:, 2 + 2 * k]) / (2 * steps[:, k, None, None])
                jac[:, :, k] = np.where(mask, d, 0.0).reshape(b, -1)
            jac_x = np.empty((b, batch.n * 4, 4))
            for k in range(4):
                d = (traj[:, 2 * p + 1 + 2 * k] - traj[:, 2 * p + 2 + 2 * k]) / (
                    2 * xsteps[:, k, None, None])
                jac_x[:, :, k] = np.where(mask, d, 0.0).reshape(b, -1)
            jtj = np.einsum('bik,bil->bkl', jac, jac)
        n_res = 4 * (batch.mask.sum(axis=0) - 1)
        dof = n_res - p
        inflation = np.maximum(1.0, (batch.mask.sum(axis=0) - 1) / np.maximum(batch.n_raw - 1, 1))
        stderr = np.full((b, p), np.nan)
        ok = (dof > 0) & np.all(np.isfinite(jtj), axis=(1, 2)) & np.isfinite(rss)
        if ok.any():
            good = np.flatnonzero(ok)
            # conditioning of the correlation form (k in N/m beside lengths in m made a
            # stiff, short stance's J^T J read singular in physical units: NaN here where
            # the reference path gave 4,000-6,500 N/m; an outside review)
            dg = np.sqrt(np.abs(np.diagonal(jtj[good], axis1=1, axis2=2)))
            dg = np.where(dg > 0, dg, 1.0)
            cond = np.linalg.cond(jtj[good] / dg[:, :, None] / dg[:, None, :])
            good = good[cond < 1e14]
            if good.size:
                cov = np.linalg.inv(jtj[good]) * (rss[good] / dof[good] * inflation[good]
                                                  )[:, None, None]
                if self.first_state_noise:
                    nvalid = np.maximum(mask.sum(axis=(1, 2)), 1)
                    s_x = first_state_covs(batch.stances, np.sum(res0**2, axis=1)
                                           / nvalid[:, None])[good]          # (G, 4, 4)
                    jx = np.einsum('bik,bil->bkl', jac[good], jac_x[good])   # Jp^T Jx
                    g = -np.linalg.solve(jtj[good], jx)                      # (G, P, 4)
                    extra = np.einsum('bpk,bkl,bql->bpq', g, s_x, g)
                    cov = cov + np.where(np.isfinite(extra), extra, np.nan)
                d = np.diagonal(cov, axis1=1, axis2=2)
                stderr[good] = np.where(d >= 0, np.sqrt(np.abs(d)), np.nan)
        return stderr, rss

    # ------------------------------------------------------------------ reference path
    def _fit_reference(self, s: Stance) -> SlipFitResult:
        model = self.model
        xe = np.asarray(s.state, dtype=float)
        t = np.asarray(s.t_s, dtype=float)
        fx0 = np.array([0.5 * (xe[:, 0].min() + xe[:, 0].max())])
        den = float(np.sum(np.sqrt(np.sum(xe**2, axis=1))))

        def objective(q: FloatArray, sc: FloatArray) -> float:
            if not (q[0] > 0 and q[1] > 0):
                return math.inf
            p = _to_physical(q[None, :], fx0, model, sc[None, :])[0]
            xm = model.simulate_reference(xe[0], p, t)
            num = float(np.sum(np.sqrt(np.sum((xm - xe) ** 2, axis=1))))
            return num / den if math.isfinite(num) else math.inf

        runs = []
        for name, k0, l0 in self._starts(s):
            sc = _scales(model)
            sc[:2] = (k0, l0)
            res = minimize(objective, np.ones(model.n_params), args=(sc,), method='Nelder-Mead',
                           options={'xatol': self.xatol, 'fatol': self.fatol,
                                    'maxiter': self.maxiter, 'maxfev': self.maxiter})
            runs.append((name, sc, res))
        f_all = np.array([float(r.fun) for _, _, r in runs])
        c_all = np.array([bool(r.success) for _, _, r in runs])
        kept = self._pick(f_all, c_all)
        name, sc, res = runs[kept]
        nfev = sum(int(r.nfev) for _, _, r in runs)
        p = _to_physical(np.asarray(res.x)[None, :], fx0, model, sc[None, :])[0]
        p_all = np.array([_to_physical(np.asarray(r.x)[None, :], fx0, model, c[None, :])[0]
                          for _, c, r in runs])
        o = other_minimum(kept, p_all, f_all, c_all)
        alt = None if o is None else (p_all[o], float(f_all[o]), runs[o][0])
        stderr = np.full(model.n_params, np.nan)
        rss = math.nan
        if self.stderr:
            xm0 = model.simulate_reference(xe[0], p, t)
            rss = float(np.sum((xm0 - xe) ** 2))
            steps = _param_steps(p, model)
            jac = np.empty((4 * (t.size - 1), model.n_params))
            for k in range(model.n_params):
                dp = np.zeros_like(p)
                dp[k] = steps[k]
                d = (model.simulate_reference(xe[0], p + dp, t)
                     - model.simulate_reference(xe[0], p - dp, t)) / (2 * steps[k])
                jac[:, k] = d[1:].ravel()
            xsteps = _X0_STEP
            jac_x = np.empty((4 * (t.size - 1), 4))
            for k in range(4):
                dx = np.zeros(4)
                dx[k] = xsteps[k]
                d = (model.simulate_reference(xe[0] + dx, p, t)
                     - model.simulate_reference(xe[0] - dx, p, t)) / (2 * xsteps[k])
                jac_x[:, k] = d[1:].ravel()
            stderr = _stderr_from_jacobian(jac, rss, 4 * (t.size - 1),
                                           max(1.0, (t.size - 1) / max(s.n_raw - 1, 1)))
            if self.first_state_noise:
                s_x = first_state_covs([s], np.mean((xm0 - xe)[1:] ** 2, axis=0)[None])[0]
                extra = np.diag(_initial_state_cov(jac, jac_x, s_x)) \
                    if np.all(np.isfinite(jac_x)) else np.full(stderr.shape, np.nan)
                stderr = np.sqrt(stderr**2 + extra)
        return self._result(s, p, stderr, float(res.fun),
                            bool(res.success and math.isfinite(res.fun)), int(res.nit),
                            nfev, rss, name, alt)

    def _result(self, s: Stance, p: FloatArray, se: FloatArray, f: float, conv: bool,
                iters: int, calls: int, rss: float, start: str,
                alt: tuple[FloatArray, float, str] | None = None) -> SlipFitResult:
        names = self.model.param_names
        # the search minimises nerr over the world-frame normaliser (a constant per stance:
        # the same optimum); reported over the stance's own (:func:`nerr_denominator`)
        rel = nerr_denominator(s.state, origin='world') / nerr_denominator(s.state)
        f_world = f
        f *= rel
        other: dict[str, Any] = {}
        if alt is not None:
            ap = dict(zip(names, map(float, alt[0])))
            other = {**ap, 'nerr': alt[1] * rel, 'start': alt[2],
                     'force_swing': spring_force_swing(s, ap)}
        return SlipFitResult(
            model=self.model.name, estimator='nerr_nelder_mead',
            params={n: float(v) for n, v in zip(names, p)},
            stderr={n: float(v) for n, v in zip(names, se)}, nerr=f, converged=conv,
            iterations=iters, evaluations=calls, samples=s.n_samples,
            touchdown_s=s.touchdown_s, liftoff_s=s.liftoff_s, tripod=s.tripod,
            label=s.label, rss=rss, start=start,
            force_swing=spring_force_swing(s, dict(zip(names, map(float, p)))),
            other_minimum=other, nerr_noise_floor=nerr_noise_floor(s), nerr_world=f_world)


#: relative forward-difference step of the position fit's Jacobian (scipy's '2-point')
_FD_STEP = float(np.sqrt(np.finfo(float).eps))


class SlipPositionFitter:
    """Least-squares fit of measured positions with the initial state free.

    Residuals are ``[bx, bz]`` model minus measurement at the raw motion-capture sample times
    (``Stance.raw_t_s``/``raw_xz_m``; the 1 kHz positions when the stance has no raw samples),
    the model starting from a free state ``(bx0, vx0, bz0, vz0)`` at ``t_s[0]``. Minimised with
    ``scipy.optimize.least_squares`` (trust region reflective, finite-difference Jacobian)
    from the spline-derived first state and each of :func:`stance_starts` (the paper's
    initial guess and the stance's own scales). Standard errors from ``s^2 (J^T J)^-1``;
    ``nerr`` of the result is Eq. 2 of the fitted trajectory against the 1 kHz state,
    comparable to :class:`SlipFitter`'s.

    From the paper's guess alone, the fit of a robot unlike EduBot stops far from its
    minimum: a 0.2 kg robot with a 0.04 m leg and k = 300 N/m read k 2,100-3,500 N/m,
    l0 0.6-1.7 m, nerr 1.3 (an outside review). The stance's scales find it.

    Parameters
    ----------
    model : SlipModel
    stride : int
        Samples per RK4 step.
    starts : {'multi', 'paper'}
        ``'multi'`` (default): every start of :func:`stance_starts`, keeping the lowest
        residual sum of squares among the converged ones (the paper's result unless another
        is lower by :attr:`RSS_RTOL` of it). ``'paper'``: the paper's guess alone. About
        1.3-7x the time of ``'paper'`` on simulated EduBot runs (walk the most).

    Attributes
    ----------
    results_ : list of SlipFitResult
        ``params``/``stderr`` hold the model parameters and ``bx0, vx0, bz0, vz0``.
    """

    STATE_NAMES = ('bx0', 'vx0', 'bz0', 'vz0')

    #: the paper's start is kept unless another start's residual sum of squares is lower by
    #: more than this fraction of it
    RSS_RTOL = 1e-6

    def __init__(self, model: SlipModel | None = None, *, stride: int = 2,
                 compiled: bool = True,
                 starts: Literal['multi', 'paper'] = 'multi') -> None:
        self.model = model if model is not None else SlipModel()
        self.stride = stride
        self.compiled = compiled
        if starts not in ('multi', 'paper'):
            raise SlipDataError(f"starts must be 'multi' or 'paper', got {starts!r}")
        self.starts = starts

    def _traj(self, p: FloatArray, x0: FloatArray, n: int, dt_s: float) -> FloatArray:
        return self._trajs(p[None, :], x0[None, :], n, dt_s)[0]

    def _trajs(self, p: FloatArray, x0: FloatArray, n: int, dt_s: float) -> FloatArray:
        """States (M, n, 4) for rows of physical parameters ``p`` from states ``x0``."""
        model = self.model
        if _kernels.HAVE_NUMBA and self.compiled:
            return _kernels.trajectories(_physical5(p, model), np.ascontiguousarray(x0), n,
                                         dt_s, self.stride, 1.0 / model.mass_kg,
                                         model.gravity_mps2, model.gravity_x_mps2)
        return np.moveaxis(model.simulate_batch(x0, p, n, dt_s, stride=self.stride), 2, 0)

    def fit(self, stances: Sequence[Stance]) -> Self:
        """Fit every stance; invalid ones raise :class:`StanceRejectedError`."""
        for s in stances:
            validate_stance(s)
        self.results_ = [self._fit_one(s) for s in stances]
        return self

    def _fit_one(self, s: Stance) -> SlipFitResult:
        model = self.model
        npar = model.n_params
        t = np.asarray(s.t_s, dtype=float)
        xe = np.asarray(s.state, dtype=float)
        if s.raw_t_s is not None and s.raw_xz_m is not None:
            t_obs = np.asarray(s.raw_t_s, dtype=float)
            y_obs = np.asarray(s.raw_xz_m, dtype=float)
        else:
            t_obs, y_obs = t, xe[:, [0, 2]]
        dt = s.dt_s
        # the grid must cover the last observation
        n = max(t.size, int(np.ceil((t_obs[-1] - t[0]) / dt - 1e-9)) + 2)
        fx0 = 0.5 * (xe[:, 0].min() + xe[:, 0].max())
        scale = np.concatenate([_scales(model), [0.01, 0.1, 0.01, 0.1]])
        # cubic Hermite from the grid to the observation times (weights computed once)
        u = (t_obs - t[0]) / dt
        ih = np.clip(np.floor(u).astype(int), 0, n - 2)
        sh = (u - ih)[:, None]
        w_h = (2 * sh**3 - 3 * sh**2 + 1, (sh**3 - 2 * sh**2 + sh) * dt,
               -2 * sh**3 + 3 * sh**2, (sh**3 - sh**2) * dt)
        y_flat = y_obs.ravel()

        def residuals(zs: FloatArray) -> FloatArray:
            """(M, 2 m) residuals of the rows of scaled parameters ``zs`` (M, P + 4)."""
            vs = zs * scale
            out = np.ones((zs.shape[0], y_flat.size))
            ok = (vs[:, 0] > 0) & (vs[:, 1] > 0)
            if ok.any():
                with np.errstate(all='ignore'):
                    tr = self._trajs(vs[ok, :npar], vs[ok, npar:], n, dt)
                    pos, vel = tr[:, :, [0, 2]], tr[:, :, [1, 3]]
                    r = (w_h[0] * pos[:, ih] + w_h[1] * vel[:, ih] + w_h[2] * pos[:, ih + 1]
                         + w_h[3] * vel[:, ih + 1]).reshape(tr.shape[0], -1) - y_flat
                out[ok] = np.where(np.isfinite(r), r, 1.0)
            return out

        last: list[Any] = [None, None]

        def residual(z: FloatArray) -> FloatArray:
            r = residuals(z[None, :])[0]
            last[:] = [z.copy(), r]
            return r

        lower = np.full(npar + 4, -np.inf)
        lower[:2] = 1e-6

        def jacobian(z: FloatArray) -> FloatArray:
            # forward differences with scipy's '2-point' steps, every column in one batch
            f0 = last[1] if last[0] is not None and np.array_equal(last[0], z) else \
                residual(z)
            h = _FD_STEP * np.where(z >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(z))
            h = np.where(z + h < lower, -h, h)
            h = (z + h) - z
            zs = z[None, :] + np.diag(h)
            return ((residuals(zs) - f0[None, :]) / h[:, None]).T

        starts = stance_starts(s, model)
        if self.starts == 'paper':
            starts = starts[:1]
        runs = []
        for name, k0, l00 in starts:
            p0 = np.zeros(npar)
            p0[:3] = (k0, l00, fx0)
            z0 = np.concatenate([p0, xe[0]]) / scale
            last[:] = [None, None]
            res = least_squares(residual, z0, jac=jacobian, bounds=(lower, np.inf),
                                method='trf', x_scale='jac', xtol=1e-10, ftol=1e-12,
                                gtol=1e-12, max_nfev=400)
            r = res.fun
            rss = float(r @ r) if np.all(np.isfinite(r)) else math.inf
            runs.append((name, res, rss, bool(res.success and res.status > 0)))
        name, res, rss = self._pick(runs)
        nfev = sum(int(run[1].nfev) for run in runs)
        v = res.x * scale
        r = res.fun
        se = _stderr_from_jacobian(res.jac / scale[None, :], rss, r.size, 1.0)
        traj = self._traj(v[:npar], v[npar:], t.size, dt)
        ne = nerr(traj, xe)
        names = model.param_names + self.STATE_NAMES
        return SlipFitResult(
            model=model.name, estimator='position_least_squares',
            params={k: float(x) for k, x in zip(names, v)},
            stderr={k: float(x) for k, x in zip(names, se)}, nerr=ne,
            converged=bool(res.success and res.status > 0 and math.isfinite(ne)),
            iterations=int(res.nfev), evaluations=nfev, samples=int(t_obs.size),
            touchdown_s=s.touchdown_s, liftoff_s=s.liftoff_s, tripod=s.tripod, label=s.label,
            rss=rss, start=name,
            force_swing=spring_force_swing(s, {k: float(x) for k, x in zip(names, v)}))

    def _pick(self, runs: list[tuple[str, Any, float, bool]]) -> tuple[str, Any, float]:
        """The start kept among ``(name, result, rss, converged)`` (the paper's first): the
        lowest residual sum of squares among the converged starts (all when none converged),
        the paper's unless another is lower by more than :attr:`RSS_RTOL` of it."""
        rss = np.array([run[2] for run in runs])
        conv = np.array([run[3] for run in runs])
        fin = np.where(conv, rss, np.inf) if conv.any() else rss
        best = int(np.argmin(fin))
        if fin[0] <= fin[best] * (1.0 + self.RSS_RTOL):
            best = 0
        return runs[best][0], runs[best][1], float(runs[best][2])
