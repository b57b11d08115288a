"""Synthetic SLIP stances with known parameters (tests and benchmarks).

Each stance starts at touchdown with the leg at rest length and ends when the leg returns to
rest length (lift-off), integrated with ``solve_ivp`` (rtol 1e-11). The trajectory is continued
with the same dynamics ``margin_s`` before and after the stance so that motion-capture samples
and splines have support around the window, as they have in a real run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from .fit import Stance
from .model import SlipModel

__all__ = ['SyntheticStance', 'make_stance', 'make_stances']


@dataclass(frozen=True, eq=False)
class SyntheticStance:
    """A synthetic stance and its truth (``params`` (P,) in model order)."""

    stance: Stance
    params: NDArray[np.float64]


#: dense solutions already integrated (:func:`_trajectory`), by model, truth, touchdown state
#: and margin, oldest dropped first: tests draw many noise realisations of one stance (60 in
#: one calibration test, each re-integrated at rtol 1e-11 took 13 of its 19 s); a solution is
#: a pure function of its key, so the stances are the same to the bit
_SOLVED: dict[tuple[object, ...], tuple[float, object]] = {}
_SOLVED_MAX = 256


def _trajectory(model: SlipModel, params: NDArray[np.float64], x_td: NDArray[np.float64],
                margin_s: float) -> tuple[float, object]:
    """Dense SLIP solution from -margin to lift-off + margin; returns (liftoff_s, sol) (the
    same solution for the same arguments, :data:`_SOLVED`)."""
    p = np.array(params, dtype=np.float64)
    x0 = np.array(x_td, dtype=np.float64)
    key = (type(model), model, p.shape, p.tobytes(), x0.tobytes(), float(margin_s))
    hit = _SOLVED.get(key)
    if hit is None:
        hit = _integrate(model, p, x0, margin_s)
        while len(_SOLVED) >= _SOLVED_MAX:
            del _SOLVED[next(iter(_SOLVED))]
        _SOLVED[key] = hit
    return hit


def _integrate(model: SlipModel, params: NDArray[np.float64], x_td: NDArray[np.float64],
               margin_s: float) -> tuple[float, object]:
    """:func:`_trajectory`'s integration (uncached)."""
    p = params
    l0 = p[1]

    def rhs(_t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
        return model.derivative(y, p)

    def liftoff(_t: float, y: NDArray[np.float64]) -> float:
        return float(np.hypot(y[0] - p[2], y[2]) - l0)

    liftoff.terminal = True  # type: ignore[attr-defined]
    liftoff.direction = 1.0  # type: ignore[attr-defined]
    fwd = solve_ivp(rhs, (0.0, 1.0), x_td, events=liftoff, rtol=1e-11, atol=1e-13,
                    dense_output=True, first_step=1e-4)
    if fwd.t_events[0].size == 0:
        raise ValueError('synthetic stance did not lift off within 1 s')
    t_lo = float(fwd.t_events[0][0])
    full = solve_ivp(rhs, (0.0, t_lo + margin_s), x_td, rtol=1e-11, atol=1e-13,
                     dense_output=True)
    back = solve_ivp(rhs, (0.0, -margin_s), x_td, rtol=1e-11, atol=1e-13, dense_output=True)

    def sol(t: NDArray[np.float64]) -> NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        out = np.empty((t.size, 4))
        neg = t < 0
        if neg.any():
            out[neg] = back.sol(t[neg]).T
        if (~neg).any():
            out[~neg] = full.sol(t[~neg]).T
        return out

    return t_lo, sol


def make_stance(params: NDArray[np.float64], *, speed_mps: float = 0.8,
                angle_rad: float = 0.3, vz_mps: float = -0.1,
                model: SlipModel | None = None, sample_hz: float = 1000.0,
                noise_m: float = 0.0, rng: np.random.Generator | None = None,
                t0_s: float = 0.0, margin_s: float = 0.05, label: str = '') -> SyntheticStance:
    """One stance sampled at 1 kHz directly or through ``sample_hz`` motion capture.

    Parameters
    ----------
    params : ndarray, shape (P,)
        True ``(k [N/m], l0 [m], fx [m], *extensions)``.
    speed_mps, vz_mps : float
        Horizontal and vertical velocity at touchdown [m/s].
    angle_rad : float
        Leg angle from vertical at touchdown, foot ahead of the mass.
    sample_hz : float
        1000 gives exact 1 kHz states; other rates sample positions at that rate with a random
        phase, add Gaussian ``noise_m`` and rebuild the 1 kHz state with a cubic spline
        (the paper's preprocessing).
    t0_s : float
        Touchdown time [s].
    """
    model = model if model is not None else SlipModel()
    rng = rng if rng is not None else np.random.default_rng(0)
    p = np.asarray(params, dtype=float)
    l0, fx = p[1], p[2]
    x_td = np.array([fx - l0 * np.sin(angle_rad), speed_mps, l0 * np.cos(angle_rad), vz_mps])
    t_lo, sol = _trajectory(model, p, x_td, margin_s)
    n = int(np.floor(t_lo * 1000.0 + 1e-9)) + 1
    t_rel = np.arange(n) * 1e-3
    if sample_hz >= 1000.0 and noise_m == 0.0:
        state = sol(t_rel)
        stance = Stance(t_s=t0_s + t_rel, state=state, label=label)
        return SyntheticStance(stance, p)
    dt = 1.0 / sample_hz
    phase = rng.uniform(0.0, dt)
    t_raw = np.arange(-margin_s + phase, t_lo + margin_s - 1e-9, dt)
    xz = sol(t_raw)[:, [0, 2]] + rng.normal(0.0, noise_m, (t_raw.size, 2))
    sx = CubicSpline(t_raw, xz[:, 0])
    sz = CubicSpline(t_raw, xz[:, 1])
    state = np.column_stack([sx(t_rel), sx(t_rel, 1), sz(t_rel), sz(t_rel, 1)])
    inside = (t_raw >= 0.0) & (t_raw <= t_rel[-1])
    stance = Stance(t_s=t0_s + t_rel, state=state, raw_t_s=t0_s + t_raw[inside],
                    raw_xz_m=xz[inside], label=label)
    return SyntheticStance(stance, p)


def make_stances(n: int, *, seed: int = 0, model: SlipModel | None = None,
                 sample_hz: float = 1000.0, noise_m: float = 0.0,
                 stiffness_npm: tuple[float, float] = (1500.0, 4000.0),
                 rest_length_m: tuple[float, float] = (0.13, 0.17),
                 speed_mps: tuple[float, float] = (0.4, 1.1),
                 angle_rad: tuple[float, float] = (0.2, 0.35)) -> list[SyntheticStance]:
    """``n`` random stances with parameters uniform in the given ranges (extensions zero)."""
    model = model if model is not None else SlipModel()
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        p = np.zeros(model.n_params)
        p[0] = rng.uniform(*stiffness_npm)
        p[1] = rng.uniform(*rest_length_m)
        p[2] = rng.uniform(0.2, 1.8)
        out.append(make_stance(p, speed_mps=rng.uniform(*speed_mps),
                               angle_rad=rng.uniform(*angle_rad),
                               vz_mps=rng.uniform(-0.25, 0.05), model=model,
                               sample_hz=sample_hz, noise_m=noise_m, rng=rng,
                               t0_s=float(i), label=f'synthetic{i}'))
    return out
