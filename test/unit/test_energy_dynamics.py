"""Inverse dynamics of the DH leg checked against independent NumPy computations."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_energy.dynamics import LegDynamics, LegSpec, mean_mechanical_power_w

SPEC = LegSpec()


def _rz(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _rx(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _links(q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(rotation of joint frame i, COM of link i) by plain DH products, base frame."""
    rot, pos, out = np.eye(3), np.zeros(3), []
    for i in range(3):
        rot_j = rot @ _rz(q[i] + SPEC.theta_offset_rad[i])
        com = pos + rot_j @ np.array([SPEC.a_m[i] / 2, 0.0, SPEC.d_m[i]])
        out.append((rot_j, com))
        pos = pos + rot_j @ np.array([SPEC.a_m[i], 0.0, SPEC.d_m[i]])
        rot = rot_j @ _rx(SPEC.alpha_rad[i])
    out.append((rot, pos))  # tip frame
    return out


def _energy(q_of_t, t: float, h: float = 1e-5) -> float:
    """Kinetic + potential energy from DH products only (velocities by central differences)."""
    a, b, c = _links(q_of_t(t - h)), _links(q_of_t(t)), _links(q_of_t(t + h))
    energy = 0.0
    r = SPEC.link_radius_m
    for i in range(3):
        m, ln = SPEC.link_masses_kg[i], SPEC.a_m[i]
        rot = b[i][0]
        v = (c[i][1] - a[i][1]) / (2 * h)
        rdot = (c[i][0] - a[i][0]) / (2 * h)
        w_hat = rdot @ rot.T
        w = np.array([w_hat[2, 1], w_hat[0, 2], w_hat[1, 0]])
        transverse = m * (3 * r**2 + ln**2) / 12
        inertia = rot @ np.diag([0.5 * m * r**2, transverse, transverse]) @ rot.T
        energy += 0.5 * m * v @ v + 0.5 * w @ inertia @ w + m * 9.81 * b[i][1][2]
    return energy


def _traj(t: np.ndarray | float):
    """A smooth, large free-air joint motion and its derivatives."""
    t = np.asarray(t, dtype=float)
    amp = np.array([0.6, -0.9, 1.3])
    q0 = np.array([0.1, 0.4, -1.2])
    w = np.array([5.0, 7.0, 11.0])
    q = q0 + amp * np.sin(w * t[..., None]) + 0.3 * t[..., None] ** 2
    qd = amp * w * np.cos(w * t[..., None]) + 0.6 * t[..., None]
    qdd = -amp * w**2 * np.sin(w * t[..., None]) + 0.6
    return q, qd, qdd


def test_forward_matches_dh_products() -> None:
    dyn = LegDynamics(SPEC)
    rng = np.random.default_rng(0)
    qs = rng.uniform(-2, 2, size=(20, 3))
    expected = np.array([_links(q)[3][1] for q in qs])
    assert_allclose(dyn.forward(qs), expected, atol=1e-14)


def test_energy_balance_free_swing() -> None:
    """Work of the RNEA torques over a contact-free motion equals the change of energy."""
    dyn = LegDynamics(SPEC)
    t_end = 0.4
    nodes, weights = np.polynomial.legendre.leggauss(80)
    t = 0.5 * t_end * (nodes + 1)
    q, qd, qdd = _traj(t)
    tau = dyn.inverse_dynamics(q, qd, qdd)
    work = 0.5 * t_end * np.sum(weights * np.sum(tau * qd, axis=1))
    d_energy = _energy(lambda s: _traj(s)[0], t_end) - _energy(lambda s: _traj(s)[0], 0.0)
    assert abs(d_energy) > 0.02  # a motion that really moves energy
    assert_allclose(work, d_energy, rtol=1e-6)


def test_ground_force_through_jacobian_is_virtual_work() -> None:
    """-J^T f equals minus the finite-difference derivative of f . tip(q)."""
    dyn = LegDynamics(SPEC)
    q = np.array([0.2, 0.5, -1.4])
    force = np.array([1.5, -0.7, 12.0])
    tau_f = dyn.inverse_dynamics(q, np.zeros(3), np.zeros(3), force) - dyn.gravity_torque(q)
    h = 1e-6
    grad = np.array([
        (force @ _links(q + h * e)[3][1] - force @ _links(q - h * e)[3][1]) / (2 * h)
        for e in np.eye(3)
    ])
    assert_allclose(tau_f[0], -grad, rtol=1e-7)


@pytest.mark.parametrize('period_s', [0.33, 1.0, 2.7])
def test_phase_scaling_equals_direct_rnea(period_s: float) -> None:
    dyn = LegDynamics(SPEC)
    phase = np.linspace(0, 1, 50, endpoint=False)
    q, d1, d2 = _traj(phase)
    stance = phase < 0.5
    pt = dyn.phase_torques(phase, q, d1, d2, stance)
    carried = 0.4
    tau = pt.torques_nm(period_s, carried)
    force = np.zeros((50, 3))
    force[stance, 2] = carried * 9.81
    direct = dyn.inverse_dynamics(q, d1 / period_s, d2 / period_s**2, force)
    assert_allclose(tau, direct, rtol=1e-12, atol=1e-12)


def test_power_definitions() -> None:
    p = np.array([[1.0, -2.0, 0.5], [-1.0, 3.0, 0.0]])
    assert_allclose(mean_mechanical_power_w(p, 'absolute'), 3.75)
    assert_allclose(mean_mechanical_power_w(p, 'positive'), 2.25)
    assert_allclose(mean_mechanical_power_w(p, 'net'), 0.75)
    assert_allclose(mean_mechanical_power_w(p), 2.25)  # the project's definition: positive
