"""Inverse dynamics and output power of the DH leg (Brodoline et al. 2024, Eq. 4-6, Fig. 7D).

The leg is a fixed-base serial chain of three revolute joints built in code with Pinocchio from
the DH table of DESIGN §7 (standard DH: ``T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``,
``theta_i = q_i + theta_offset_i``).  Each link is a slender rod of its DESIGN §7 mass lying along
its DH x axis, centre of mass at ``a_i / 2``.  The leg base frame has z up; gravity is
``(0, 0, -9.81) m/s^2``.

Joint torques along a trajectory (Eq. 5)::

    tau = M(q) qdd + C(q, qd) qd + G(q) - J(q)^T f

with ``f = (0, 0, (m_c + m_leg) g)`` the ground reaction force on the tip while the leg is in
stance (Eq. 4: ``m_c`` the mass the leg carries, Eq. 2 /
:func:`hexapod_gait.gait.carried_mass_per_leg_kg`, plus the leg's own mass: the stance tips
carry ``M g`` together), zero in swing; ``J`` is the linear part of the tip Jacobian in
base-aligned axes.

Average mechanical (output) power, Eq. 6.  **Definition used here, and everywhere in
hexapod_energy** (the ``energy_monitor`` node from joint efforts, the offline analysis, this
model)::

    P_out = (1 / T) * integral_0^T  sum_j max(tau_j(t) qd_j(t), 0)  dt

the mean *positive* joint power: the work the actuators deliver.  Servomotors do not regenerate
(the bridge dissipates braking energy, it never returns it to the supply), so negative joint work
is not a credit (the signed mean, ``'net'``, is zero for conservative periodic motion) and it is
not an output either: while a joint is back-driven the load works on the servo, whose loss of
that energy is part of ``P_loss``.  The integral is over one period sampled uniformly in phase
(exact to the sampling for a periodic trajectory).

Not the authors' definition.  Eq. 6 itself is not in the paper's text we hold; the authors'
published code (MiMiC-Ant ``p1_legSimulation.m``) sums ``|tau qd|`` (``'absolute'``), which
on a periodic path whose ground force does no net work is exactly twice the positive part.
With it the simulated AntBot's tripod (beta 0.5) has its lowest efficiency on the bench's speeds
at 1.30 % (0.092 m/s), inside the paper's text's "min(eta) between 1.1 and 2.0 %", where the
positive part gives 0.65 %; but its efficiency at 0.6 m/s becomes 12 %, outside the 0.5-6 %
band the project's simulator is held to.  The paper's P_out also differs in two ways this
model does not follow (an outside review of the equations): its Eq. 4 adds a horizontal
ground force along the line from the tip to the centre of mass (the authors' code:
``F_x = F_z (x_tip - x_COM) / z_tip``; x3.4 on P_out at 0.1 m/s, x1.6 at 0.6 m/s with the
positive part), and its stance tip is 180 mm out and 115 mm down (here 140 and 120 mm: x1.8
at 0.1 m/s, x1.0 at 0.6 m/s).  ``OutputPowerModel(definition='absolute')`` gives the authors'
sum.

Speed scaling.  A gait's joint path in *phase* ``phi = t / T`` does not depend on ``T``.  With
``q' = dq/dphi`` and ``q'' = d2q/dphi2``, ``qd = q' / T`` and ``qdd = q'' / T^2`` so that::

    tau(T, m) = G(q) + H(q, q', q'') / T^2 - m g J^T e_z     (m = m_c + m_leg in stance)

with ``H = RNEA(q, q', q'') - G``: one RNEA pass per phase sample serves every period and every
load.  This is what makes the 50 x 50 power map a NumPy expression (:func:`power_map`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.metrics import G_MPS2

__all__ = [
    'ANTBOT_LEG_SPEC',
    'LegDynamics',
    'LegSpec',
    'PhaseTorques',
    'PowerDefinition',
    'build_leg_model',
    'mean_mechanical_power_w',
]

PowerDefinition = Literal['absolute', 'positive', 'net']


@dataclass(frozen=True)
class LegSpec:
    """DH table and link masses of a 3-DOF leg (DESIGN §7 defaults).

    Attributes
    ----------
    a_m, alpha_rad, d_m, theta_offset_rad : tuple of 3 floats
        Standard DH parameters [m, rad].
    link_masses_kg : tuple of 3 floats
        Coxa, femur, tibia masses [kg].
    link_radius_m : float
        Radius of the rod model, only for the (small) axial inertia [m].
    """

    a_m: tuple[float, float, float] = (0.053, 0.083, 0.146)
    alpha_rad: tuple[float, float, float] = (np.pi / 2, 0.0, 0.0)
    d_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    theta_offset_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    link_masses_kg: tuple[float, float, float] = (0.01498, 0.1118, 0.03923)
    link_radius_m: float = 0.005

    @property
    def leg_mass_kg(self) -> float:
        """Total mass of the leg [kg]."""
        return float(sum(self.link_masses_kg))

    @classmethod
    def from_dh(cls, dh: Any) -> LegSpec:
        """Build from any object with ``a_m, alpha_rad, d_m`` (and optionally
        ``theta_offset_rad``, ``link_masses_kg``), e.g.
        ``hexapod_gait.kinematics.DHParameters``."""
        kw: dict[str, Any] = {
            'a_m': tuple(float(x) for x in dh.a_m),
            'alpha_rad': tuple(float(x) for x in dh.alpha_rad),
            'd_m': tuple(float(x) for x in dh.d_m),
        }
        for name in ('theta_offset_rad', 'link_masses_kg'):
            if getattr(dh, name, None) is not None:
                kw[name] = tuple(float(x) for x in getattr(dh, name))
        return cls(**kw)


ANTBOT_LEG_SPEC = LegSpec()


def _rod_inertia(mass_kg: float, length_m: float, radius_m: float) -> pin.Inertia:
    axial = 0.5 * mass_kg * radius_m**2
    transverse = mass_kg * (3.0 * radius_m**2 + length_m**2) / 12.0
    return pin.Inertia(
        mass_kg, np.array([length_m / 2.0, 0.0, 0.0]), np.diag([axial, transverse, transverse])
    )


def build_leg_model(spec: LegSpec = ANTBOT_LEG_SPEC) -> pin.Model:
    """Pinocchio model of the DH leg with an operational frame ``'tip'``.

    Joint ``i`` (``JointModelRZ``) sits at DH frame ``i-1`` rotated by ``theta_offset_i``; its body
    is the rod of link ``i``; the next joint is placed at ``Tz(d_i) Tx(a_i) Rx(alpha_i)``.
    """
    model = pin.Model()
    model.name = 'dh_leg'
    parent = 0
    placement = pin.SE3.Identity()
    names = ('coxa', 'femur', 'tibia')
    for i in range(3):
        offset = pin.SE3(pin.utils.rotate('z', spec.theta_offset_rad[i]), np.zeros(3))
        jid = model.addJoint(parent, pin.JointModelRZ(), placement * offset, names[i])
        model.appendBodyToJoint(
            jid,
            _rod_inertia(spec.link_masses_kg[i], spec.a_m[i], spec.link_radius_m),
            pin.SE3.Identity(),
        )
        placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, spec.d_m[i]])) * pin.SE3(
            pin.utils.rotate('x', spec.alpha_rad[i]), np.array([spec.a_m[i], 0.0, 0.0])
        )
        parent = jid
    model.addFrame(pin.Frame('tip', parent, 0, placement, pin.FrameType.OP_FRAME))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -G_MPS2, 0.0, 0.0, 0.0]))
    return model


def _as_q(x: Any, name: str) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InvalidInputError(f'{name} must have shape (n, 3) or (3,), got {arr.shape}')
    return arr


class LegDynamics:
    """Rigid-body dynamics of one DH leg (Pinocchio).

    Parameters
    ----------
    spec : LegSpec
        DH table and masses.
    """

    def __init__(self, spec: LegSpec = ANTBOT_LEG_SPEC) -> None:
        self.spec = spec
        self.model = build_leg_model(spec)
        self.data = self.model.createData()
        self.tip_frame_id = self.model.getFrameId('tip')

    def forward(self, q: Any) -> np.ndarray:
        """Tip position in the leg base frame, (n, 3) [m] for q (n, 3) [rad]."""
        qs = _as_q(q, 'q')
        out = np.empty_like(qs)
        for k, qk in enumerate(qs):
            pin.framesForwardKinematics(self.model, self.data, qk)
            out[k] = self.data.oMf[self.tip_frame_id].translation
        return out

    def tip_jacobian(self, q: Any) -> np.ndarray:
        """Linear tip Jacobian in base-aligned axes, (n, 3, 3) [m/rad]."""
        qs = _as_q(q, 'q')
        out = np.empty((len(qs), 3, 3))
        for k, qk in enumerate(qs):
            jac = pin.computeFrameJacobian(
                self.model, self.data, qk, self.tip_frame_id, pin.LOCAL_WORLD_ALIGNED
            )
            out[k] = jac[:3]
        return out

    def gravity_torque(self, q: Any) -> np.ndarray:
        """G(q), (n, 3) [N m]."""
        qs = _as_q(q, 'q')
        return np.array([pin.computeGeneralizedGravity(self.model, self.data, qk) for qk in qs])

    def inverse_dynamics(
        self, q: Any, qd: Any, qdd: Any, tip_force_n: Any | None = None
    ) -> np.ndarray:
        """Joint torques ``M qdd + C qd + G - J^T f`` (Eq. 5), (n, 3) [N m].

        Parameters
        ----------
        q, qd, qdd : array (n, 3)
            Joint positions [rad], velocities [rad/s], accelerations [rad/s^2].
        tip_force_n : array (n, 3) or (3,), optional
            Force the ground exerts on the tip, base-aligned axes [N]; None for free motion.
        """
        qs, qds, qdds = _as_q(q, 'q'), _as_q(qd, 'qd'), _as_q(qdd, 'qdd')
        if not (len(qs) == len(qds) == len(qdds)):
            raise InvalidInputError(
                f'q, qd, qdd must have the same length, got {len(qs)}, {len(qds)}, {len(qdds)}'
            )
        tau = np.array(
            [pin.rnea(self.model, self.data, a, b, c) for a, b, c in zip(qs, qds, qdds)]
        )
        if tip_force_n is not None:
            force = np.broadcast_to(np.asarray(tip_force_n, dtype=float), tau.shape)
            tau = tau - np.einsum('nij,ni->nj', self.tip_jacobian(qs), force)
        return tau

    def phase_torques(
        self,
        phase: Any,
        q: Any,
        dq_dphase: Any,
        d2q_dphase2: Any,
        stance: Any,
    ) -> PhaseTorques:
        """Decompose the torques of a phase-parameterised joint path (see module docstring).

        Parameters
        ----------
        phase : array (n,)
            Uniform samples of one cycle, in [0, 1).
        q, dq_dphase, d2q_dphase2 : array (n, 3)
            Joint path and its first two phase derivatives [rad, rad, rad].
        stance : array (n,) of bool
            Whether the tip is on the ground at each sample.
        """
        qs = _as_q(q, 'q')
        d1 = _as_q(dq_dphase, 'dq_dphase')
        d2 = _as_q(d2q_dphase2, 'd2q_dphase2')
        gravity = self.gravity_torque(qs)
        inertial = self.inverse_dynamics(qs, d1, d2) - gravity
        jac = self.tip_jacobian(qs)
        # torque per kg carried: -J^T (0, 0, g)
        per_kg = -G_MPS2 * jac[:, 2, :]
        return PhaseTorques(
            phase=np.asarray(phase, dtype=float),
            q=qs,
            dq_dphase=d1,
            gravity_nm=gravity,
            inertial_nm_s2=inertial,
            per_carried_kg_nm=per_kg,
            stance=np.asarray(stance, dtype=bool),
        )


@dataclass(frozen=True)
class PhaseTorques:
    """Torque decomposition of one leg's phase-parameterised path.

    ``tau(T, m_c) = gravity_nm + inertial_nm_s2 / T^2 + m_c * per_carried_kg_nm * stance``.

    Attributes
    ----------
    phase : (n,)            uniform phase samples in [0, 1)
    q : (n, 3)              joint angles [rad]
    dq_dphase : (n, 3)      dq/dphi [rad]; joint velocity is dq_dphase / T
    gravity_nm : (n, 3)     G(q) [N m]
    inertial_nm_s2 : (n, 3) RNEA(q, q', q'') - G(q) [N m s^2]
    per_carried_kg_nm : (n, 3)  -g J^T e_z [N m / kg]
    stance : (n,) bool
    """

    phase: np.ndarray
    q: np.ndarray
    dq_dphase: np.ndarray
    gravity_nm: np.ndarray
    inertial_nm_s2: np.ndarray
    per_carried_kg_nm: np.ndarray
    stance: np.ndarray = field(repr=False)

    def torques_nm(self, period_s: float, carried_mass_kg: Any = 0.0) -> np.ndarray:
        """Joint torques (n, 3) [N m] at period ``period_s`` with ``carried_mass_kg``
        (scalar or (n,)) on the tip during stance."""
        m = np.broadcast_to(np.asarray(carried_mass_kg, dtype=float), self.phase.shape)
        return (
            self.gravity_nm
            + self.inertial_nm_s2 / period_s**2
            + (m * self.stance)[:, None] * self.per_carried_kg_nm
        )

    def joint_power_w(self, period_s: float, carried_mass_kg: Any = 0.0) -> np.ndarray:
        """Joint powers ``tau_j qd_j`` (n, 3) [W]."""
        return self.torques_nm(period_s, carried_mass_kg) * self.dq_dphase / period_s


def mean_mechanical_power_w(
    joint_power_w: Any, definition: PowerDefinition = 'positive', axis: int | Sequence[int] = 0
) -> np.ndarray:
    """Average mechanical power (Eq. 6) from uniformly sampled joint powers.

    Parameters
    ----------
    joint_power_w : array (..., n, 3) or (n, 3)
        ``tau_j qd_j`` at uniform samples of one period [W].
    definition : {'absolute', 'positive', 'net'}
        ``mean(sum_j |p_j|)``, ``mean(sum_j max(p_j, 0))`` (default, see module docstring) or
        ``mean(sum_j p_j)``.
    axis : int
        Axis of the time samples.
    """
    p = np.asarray(joint_power_w, dtype=float)
    if definition == 'absolute':
        p = np.abs(p)
    elif definition == 'positive':
        p = np.clip(p, 0.0, None)
    elif definition != 'net':
        raise InvalidInputError(
            f"definition must be 'absolute', 'positive' or 'net', got {definition!r}"
        )
    return np.mean(np.sum(p, axis=-1), axis=axis)
