"""The SLIP template of Komsuoglu et al. (Eq. 1) and its integrators.

A point mass ``m`` rides on a massless spring leg of stiffness ``k`` and rest length ``l0``
whose foot is pinned at ``(fx, 0)`` on the ground:

    b'' = -(k / m) (||b - f|| - l0) (b - f) / ||b - f|| + (g_x, -g_z)

with gravity ``(g_x, -g_z)`` in the ground frame: ``g_z = gravity_mps2`` (9.81 m/s^2 on level
ground) and ``g_x = gravity_x_mps2`` (0 unless gravity is taken from a motion-capture frame
levelled to it on a slope: ``g sin(slope)`` downhill along the travel, ``g_z = g cos``).

State order everywhere: ``[bx, bx', bz, bz']`` (m, m/s, m, m/s), sagittal world frame, z up.

Template extensions (issue 8, the residual loop) add named parameters after ``(k, l0, fx)``:

``leg_damping``
    ``c`` [N s/m], radial viscous force ``-c * dr/dt`` along the leg.
``hip_torque``
    ``tau`` [N m], a constant torque about the foot; the force ``tau / r`` acts perpendicular to
    the leg, positive pushing the body forward (+x) when it is above the foot.

Two integrators: :meth:`SlipModel.simulate_batch` (fixed-step RK4 vectorised over a batch of
parameter sets, with cubic Hermite output on the sample grid; the fast path) and
:meth:`SlipModel.simulate_reference` (``solve_ivp`` DOP853, rtol 1e-10; the reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from .errors import SlipDataError

__all__ = [
    'BASE_PARAMETERS',
    'EXTENSIONS',
    'EDUBOT_MASS_KG',
    'GRAVITY_MPS2',
    'SlipModel',
]

EDUBOT_MASS_KG = 3.31
GRAVITY_MPS2 = 9.81
BASE_PARAMETERS: tuple[str, ...] = ('stiffness', 'rest_length', 'foot_x')
#: extension name -> (unit, normalisation scale used by the Nelder-Mead fit)
EXTENSIONS: dict[str, tuple[str, float]] = {
    'leg_damping': ('N s/m', 10.0),
    'hip_torque': ('N m', 1.0),
}

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SlipModel:
    """SLIP template with optional named extensions.

    Parameters
    ----------
    mass_kg : float
        Point mass [kg], EduBot 3.31 kg.
    gravity_mps2 : float
        Gravitational acceleration [m/s^2].
    extensions : tuple of str
        Names from :data:`EXTENSIONS` (``'leg_damping'``, ``'hip_torque'``), in any order.
    gravity_x_mps2 : float
        Gravity's component along the ground frame's x (the travel) [m/s^2]; then
        ``gravity_mps2`` is its component into the ground. 0 by default: gravity normal to
        the ground (:meth:`with_gravity`).
    """

    mass_kg: float = EDUBOT_MASS_KG
    gravity_mps2: float = GRAVITY_MPS2
    extensions: tuple[str, ...] = ()
    gravity_x_mps2: float = 0.0

    def with_gravity(self, gravity_world: ArrayLike) -> SlipModel:
        """This model with gravity ``(gx, gy, gz)`` [m/s^2] given in the ground frame (z up,
        x along the travel; e.g. ``R @ (0, 0, -9.81)`` for a frame whose rows ``R`` are the
        ground axes in a motion-capture frame levelled to gravity): its sagittal part
        ``gx`` along x and ``-gz`` into the ground (the lateral part is outside the plane)."""
        g = np.asarray(gravity_world, dtype=float)
        return SlipModel(mass_kg=self.mass_kg, gravity_mps2=float(-g[2]),
                         extensions=self.extensions, gravity_x_mps2=float(g[0]))

    def __post_init__(self) -> None:
        if not self.mass_kg > 0:
            raise SlipDataError(f'mass_kg must be > 0, got {self.mass_kg!r}')
        unknown = [e for e in self.extensions if e not in EXTENSIONS]
        if unknown:
            raise SlipDataError(
                f'unknown SLIP extension(s) {unknown}; expected names from {sorted(EXTENSIONS)}')
        if len(set(self.extensions)) != len(self.extensions):
            raise SlipDataError(f'extensions repeated: {self.extensions}')

    @classmethod
    def from_name(cls, name: str, *, mass_kg: float = EDUBOT_MASS_KG) -> SlipModel:
        """Build from a model name such as ``'slip'`` or ``'slip+leg_damping+hip_torque'``."""
        parts = name.split('+')
        if parts[0] != 'slip':
            raise SlipDataError(f"model name {name!r} must start with 'slip'")
        return cls(mass_kg=mass_kg, extensions=tuple(parts[1:]))

    @property
    def name(self) -> str:
        """``'slip'`` or ``'slip+<ext>+...'`` (the ``SlipFit.model`` field)."""
        return '+'.join(('slip',) + self.extensions)

    @property
    def param_names(self) -> tuple[str, ...]:
        """``('stiffness', 'rest_length', 'foot_x', *extensions)``."""
        return BASE_PARAMETERS + self.extensions

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    # ------------------------------------------------------------------ dynamics
    def _accel(self, bx: FloatArray, vx: FloatArray, bz: FloatArray, vz: FloatArray,
               p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Acceleration of the mass; arrays broadcast, ``p`` is (P, M)."""
        inv_m = 1.0 / self.mass_kg
        dx = bx - p[2]
        r2 = dx * dx + bz * bz
        r = np.sqrt(r2)
        s = (p[0] * inv_m) * (p[1] / r - 1.0)
        ax_extra = 0.0
        az_extra = 0.0
        for j, ext in enumerate(self.extensions, start=3):
            if ext == 'leg_damping':
                s = s - (p[j] * inv_m) * (dx * vx + bz * vz) / r2
            else:  # hip_torque
                t = (p[j] * inv_m) / r2
                ax_extra = ax_extra + t * bz
                az_extra = az_extra - t * dx
        ax = s * dx + ax_extra + self.gravity_x_mps2
        az = s * bz + az_extra - self.gravity_mps2
        return ax, az

    def derivative(self, state: ArrayLike, params: ArrayLike) -> FloatArray:
        """Time derivative of the state.

        Parameters
        ----------
        state : array_like, shape (4,) or (4, M)
        params : array_like, shape (P,) or (P, M)

        Returns
        -------
        ndarray, same shape as ``state``
        """
        x = np.asarray(state, dtype=float)
        p = np.asarray(params, dtype=float)
        ax, az = self._accel(x[0], x[1], x[2], x[3], p)
        return np.stack(np.broadcast_arrays(x[1], ax, x[3], az))

    # ------------------------------------------------------------------ integrators
    def simulate_batch(self, x0: ArrayLike, params: ArrayLike, n_samples: int, dt_s: float,
                       *, stride: int = 2) -> FloatArray:
        """Fixed-step RK4 over a batch, output on the uniform sample grid.

        RK4 runs with step ``stride * dt_s``; the states between grid points come from cubic
        Hermite interpolation with the exact derivatives at the grid points (error
        O(h^4), far below motion-capture noise for stride <= 4 at 1 kHz).

        Parameters
        ----------
        x0 : array_like, shape (M, 4)
            Initial states [bx, bx', bz, bz'] at sample 0.
        params : array_like, shape (M, P)
            Physical parameters in :attr:`param_names` order.
        n_samples : int
            Number of output samples N (sample 0 is ``x0``).
        dt_s : float
            Sample interval [s].
        stride : int
            Samples per RK4 step.

        Returns
        -------
        ndarray, shape (N, 4, M)
            States at ``t0 + i * dt_s``; non-finite where the trajectory blew up.
        """
        x = np.array(np.asarray(x0, dtype=float).T, order='C')  # (4, M)
        p = np.ascontiguousarray(np.asarray(params, dtype=float).T)  # (P, M)
        if x.shape[0] != 4 or p.shape[0] != self.n_params or x.shape[1] != p.shape[1]:
            raise SlipDataError(
                f'simulate_batch expects x0 (M, 4) and params (M, {self.n_params}); '
                f'got {np.shape(x0)} and {np.shape(params)}')
        stride = max(1, int(stride))
        h = stride * dt_s
        n_grid = (n_samples - 1 + stride - 1) // stride  # RK4 steps
        m = x.shape[1]
        xs = np.empty((n_grid + 1, 4, m))
        fs = np.empty((n_grid + 1, 4, m))
        accel = self._accel

        def deriv(y: FloatArray, out: FloatArray) -> FloatArray:
            out[0] = y[1]
            out[2] = y[3]
            out[1], out[3] = accel(y[0], y[1], y[2], y[3], p)
            return out

        k2 = np.empty((4, m))
        k3 = np.empty((4, m))
        k4 = np.empty((4, m))
        xs[0] = x
        deriv(x, fs[0])
        with np.errstate(all='ignore'):
            for i in range(n_grid):
                k1 = fs[i]
                deriv(x + (0.5 * h) * k1, k2)
                deriv(x + (0.5 * h) * k2, k3)
                deriv(x + h * k3, k4)
                k2 += k3
                k2 *= 2.0
                k2 += k1
                k2 += k4
                x = x + (h / 6.0) * k2
                xs[i + 1] = x
                deriv(x, fs[i + 1])
            if stride == 1:
                return xs[:n_samples]
            out = np.empty((n_grid * stride + 1, 4, m))
            out[::stride] = xs
            y0, y1, f0, f1 = xs[:-1], xs[1:], fs[:-1], fs[1:]
            for j in range(1, stride):
                s = j / stride
                h00 = 2 * s**3 - 3 * s**2 + 1
                h10 = s**3 - 2 * s**2 + s
                h01 = -2 * s**3 + 3 * s**2
                h11 = s**3 - s**2
                out[j::stride] = h00 * y0 + (h10 * h) * f0 + h01 * y1 + (h11 * h) * f1
        return out[:n_samples]

    def simulate_reference(self, x0: ArrayLike, params: ArrayLike, t_s: ArrayLike, *,
                           rtol: float = 1e-10, atol: float = 1e-12) -> FloatArray:
        """High-accuracy trajectory with ``solve_ivp`` (DOP853).

        Parameters
        ----------
        x0 : array_like, shape (4,)
            State at ``t_s[0]``.
        params : array_like, shape (P,)
        t_s : array_like, shape (N,)
            Increasing output times [s].

        Returns
        -------
        ndarray, shape (N, 4)
            States at ``t_s``; NaN rows after a failed integration.
        """
        t = np.asarray(t_s, dtype=float)
        p = np.asarray(params, dtype=float)
        y0 = np.asarray(x0, dtype=float)
        out = np.full((t.size, 4), np.nan)
        if t.size == 1:
            out[0] = y0
            return out

        def rhs(_t: float, y: FloatArray) -> FloatArray:
            ax, az = self._accel(y[0], y[1], y[2], y[3], p)
            return np.array([y[1], ax, y[3], az])

        with np.errstate(all='ignore'):
            sol = solve_ivp(rhs, (t[0], t[-1]), y0, method='DOP853', t_eval=t,
                            rtol=rtol, atol=atol)
        n = sol.y.shape[1]
        out[:n] = sol.y.T
        return out

    def touchdown_state(self, params: ArrayLike, *, speed_mps: float,
                        angle_rad: float) -> FloatArray:
        """State at touchdown with the leg at rest length.

        Parameters
        ----------
        params : array_like, shape (P,)
        speed_mps : float
            Speed of the mass at touchdown.
        angle_rad : float
            Leg angle from vertical, positive with the foot ahead of the mass, and velocity
            direction ``-angle_rad`` below the horizontal (a symmetric running stance).

        Returns
        -------
        ndarray, shape (4,)
        """
        p = np.asarray(params, dtype=float)
        l0, fx = p[1], p[2]
        bx = fx - l0 * np.sin(angle_rad)
        bz = l0 * np.cos(angle_rad)
        return np.array([bx, speed_mps * np.cos(angle_rad), bz,
                         -speed_mps * np.sin(angle_rad)])
