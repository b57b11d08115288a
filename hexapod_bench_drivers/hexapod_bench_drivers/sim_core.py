"""Shared pieces of the servo-leg simulators: leg loads, supply, sensor noise, the trace.

Core module (numpy, pinocchio; no ROS). The simulators produce a :class:`SimTrace` of arrays;
``sim_bag`` turns a trace into the real drivers' messages.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from hexapod_gait.kinematics import ANTBOT_LEG, DHParameters, LegKinematics
from hexapod_gait.leg_file import LegFile
from hexapod_gait.trajectory import ANTBOT_NEUTRAL_TIP_M

__all__ = [
    'G_MPS2',
    'LegLoads',
    'antbot_leg',
    'leg_summary',
    'resolve_leg',
    'SessionRecord',
    'SimTrace',
    'Supply',
    'TraceBuilder',
]

G_MPS2 = 9.81
_AX_TICK_RAD = math.radians(300.0 / 1023.0)

FloatArray = NDArray[np.float64]


def antbot_leg() -> LegFile:
    """AntBot's leg (DESIGN section 7: DH table, link masses, neutral tip), the simulators'
    default."""
    return LegFile(ANTBOT_LEG, tuple(ANTBOT_NEUTRAL_TIP_M), 'AntBot')  # type: ignore[arg-type]


def resolve_leg(leg: LegFile | None = None, dh: DHParameters | None = None) -> LegFile:
    """The leg a simulator walks: ``leg`` (a leg file, :func:`hexapod_gait.leg_file.
    read_leg_file`: its DH table, link masses and neutral tip), else ``dh`` with AntBot's
    neutral tip, else AntBot's leg. Both given is refused (ValueError)."""
    if leg is not None and dh is not None:
        raise ValueError('give the simulator a leg (leg file) or a DH table, not both')
    if leg is not None:
        return leg
    if dh is None or dh == ANTBOT_LEG:
        return antbot_leg()
    return LegFile(dh, tuple(ANTBOT_NEUTRAL_TIP_M), 'DH table')  # type: ignore[arg-type]


def leg_summary(leg: LegFile) -> dict[str, Any]:
    """JSON-able description of the simulated leg (the bag's ``hexapod_sim.config``
    ``leg_description``), the keys of a leg file."""
    dh = leg.dh
    return {'name': leg.name, 'a_m': list(dh.a_m), 'alpha_rad': list(dh.alpha_rad),
            'd_m': list(dh.d_m), 'theta_offset_rad': list(dh.theta_offset_rad),
            'link_masses_kg': list(dh.link_masses_kg),
            'joint_limits_rad': [list(x) for x in dh.joint_limits_rad],
            'neutral_tip_m': list(leg.neutral_tip_m)}


def _rod(mass_kg: float, length_m: float, radius_m: float = 0.005) -> pin.Inertia:
    axial = 0.5 * mass_kg * radius_m ** 2
    transverse = mass_kg * (3.0 * radius_m ** 2 + length_m ** 2) / 12.0
    return pin.Inertia(mass_kg, np.array([length_m / 2.0, 0.0, 0.0]),
                       np.diag([axial, transverse, transverse]))


class LegLoads:
    """Joint torques a 3-DOF DH leg needs: ``tau = M qdd + C qd + G - J^T f``.

    Links are rods along their DH x axes (centre of mass at ``a_i / 2``), the base frame has z
    up and gravity ``-g e_z``; ``f`` is the force the ground applies on the tip (base-aligned).

    Parameters
    ----------
    dh : DHParameters
        DH table and link masses (DESIGN section 7 by default).
    """

    def __init__(self, dh: DHParameters = ANTBOT_LEG) -> None:
        self.dh = dh
        self.kinematics = LegKinematics(dh)
        model = pin.Model()
        parent = 0
        placement = pin.SE3.Identity()
        for i, name in enumerate(('coxa', 'femur', 'tibia')):
            offset = pin.SE3(pin.utils.rotate('z', dh.theta_offset_rad[i]), np.zeros(3))
            jid = model.addJoint(parent, pin.JointModelRZ(), placement * offset, name)
            model.appendBodyToJoint(jid, _rod(dh.link_masses_kg[i], dh.a_m[i]),
                                    pin.SE3.Identity())
            placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, dh.d_m[i]])) * pin.SE3(
                pin.utils.rotate('x', dh.alpha_rad[i]), np.array([dh.a_m[i], 0.0, 0.0]))
            parent = jid
        model.gravity = pin.Motion(np.array([0.0, 0.0, -G_MPS2, 0.0, 0.0, 0.0]))
        self.model = model
        self.data = model.createData()

    def joint_inertia_kgm2(self, q: ArrayLike) -> FloatArray:
        """Diagonal of the joint-space inertia matrix ``M(q)``, shape (3,) [kg m^2]."""
        m = pin.crba(self.model, self.data, np.asarray(q, dtype=float))
        return np.array(np.diag(m), dtype=float)

    def static_torques(self, q: ArrayLike, tip_force_n: ArrayLike | None = None) -> FloatArray:
        """Quasi-static joint loads ``G(q) - J^T f``, shape (n, 3) [N m] (vectorised).

        The links are rods with their centre of mass on the DH x axes, so the gravity torque
        follows from the heights of the centres of mass.
        """
        qs = np.atleast_2d(np.asarray(q, dtype=float))
        a1, a2, a3 = self.dh.a_m
        m1, m2, m3 = self.dh.link_masses_kg
        th = qs + np.asarray(self.dh.theta_offset_rad)
        c2 = np.cos(th[:, 1])
        c23 = np.cos(th[:, 1] + th[:, 2])
        tau = np.zeros_like(qs)
        tau[:, 1] = G_MPS2 * (m2 * a2 / 2 * c2 + m3 * (a2 * c2 + a3 / 2 * c23))
        tau[:, 2] = G_MPS2 * m3 * a3 / 2 * c23
        if tip_force_n is not None:
            force = np.broadcast_to(np.asarray(tip_force_n, dtype=float), qs.shape)
            jac = self.kinematics.jacobian(qs).reshape(-1, 3, 3)
            tau = tau - np.einsum('nij,ni->nj', jac, force)
        return tau

    @property
    def leg_mass_kg(self) -> float:
        """Mass of the leg's links [kg]."""
        return float(sum(self.dh.link_masses_kg))

    def torques(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike,
                tip_force_n: ArrayLike | None = None) -> FloatArray:
        """Required joint torques, shape (n, 3) [N m] for q, qd, qdd of shape (n, 3).

        ``tip_force_n`` (n, 3) or (3,) is the ground's force on the tip [N] (None: free leg).
        """
        qs = np.atleast_2d(np.asarray(q, dtype=float))
        qds = np.atleast_2d(np.asarray(qd, dtype=float))
        qdds = np.atleast_2d(np.asarray(qdd, dtype=float))
        tau = np.empty_like(qs)
        for k in range(qs.shape[0]):
            tau[k] = pin.rnea(self.model, self.data, qs[k], qds[k], qdds[k])
        if tip_force_n is not None:
            force = np.broadcast_to(np.asarray(tip_force_n, dtype=float), qs.shape)
            jac = self.kinematics.jacobian(qs).reshape(-1, 3, 3)
            tau = tau - np.einsum('nij,ni->nj', jac, force)
        return tau


@dataclass
class Supply:
    """Voltage source feeding the servos: lab supply or 3S LiPo, plus series resistance.

    ``kind='supply'``: constant ``voltage_v``. ``kind='battery'``: open-circuit voltage
    ``11.1 + 1.5 soc`` V falling with the charge drawn from ``capacity_ah``, internal resistance
    ``internal_resistance_ohm``. ``series_resistance_ohm`` is the ``supply_resistance`` effect.
    The terminal voltage and the current of a sample are solved together
    (:func:`powered_step`): ``V = V_source(I) - R I`` holds on every sample. (It used the
    previous sample's current: with 0.35 ohm at 0.6 m/s, whose current swings by amperes from one
    10 ms sample to the next, V missed ``V_source - R I`` by 0.72 V rms, a fit of V on I gave
    0.215 ohm, and the start-up rang down to 5.35 V.)
    """

    kind: str = 'supply'
    voltage_v: float = 11.9
    capacity_ah: float = 2.2
    internal_resistance_ohm: float = 0.03
    series_resistance_ohm: float = 0.0
    state_of_charge: float = 1.0
    current_a: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ('supply', 'battery'):
            raise ValueError(f"Supply.kind = {self.kind!r}: expected 'supply' or 'battery'")

    def source_voltage_v(self, current_a: float | None = None) -> float:
        """Voltage of the ideal source behind the series resistance [V], at ``current_a``
        (default: the last sample's current)."""
        i = self.current_a if current_a is None else float(current_a)
        if self.kind == 'supply':
            return self.voltage_v
        return 11.1 + 1.5 * self.state_of_charge - self.internal_resistance_ohm * i

    def terminal_voltage_v(self, current_a: float | None = None) -> float:
        """Voltage at the monitor and the robot [V], at ``current_a`` (default: the last
        sample's current)."""
        i = self.current_a if current_a is None else float(current_a)
        return self.source_voltage_v(i) - self.series_resistance_ohm * i

    @property
    def resistance_ohm(self) -> float:
        """Total resistance between the ideal source and the terminals [ohm]."""
        return self.series_resistance_ohm + (self.internal_resistance_ohm
                                             if self.kind == 'battery' else 0.0)

    def draw(self, current_a: float, dt_s: float) -> None:
        """Record the current drawn over the last ``dt_s`` seconds."""
        self.current_a = float(current_a)
        if self.kind == 'battery':
            self.state_of_charge = max(
                0.0, self.state_of_charge - current_a * dt_s / 3600.0 / self.capacity_ah)


def powered_step(servos: Any, supply: Supply, dt_s: float, goal_rad: Any, external_nm: Any,
                 extra_w: float = 0.0, *, tol_v: float = 1e-4) -> tuple[Any, float, float]:
    """Step ``servos`` over one sample at the terminal voltage their own current sets.

    The current ``I(V)`` the servos (plus ``extra_w`` of other loads) draw over the sample
    depends on the voltage they see, and the voltage on the current through the supply's
    resistance: ``V = V_source(I) - R I``. Solved by a secant on the servo step (it is nearly
    linear in ``V``): at most three steps from the same state, one when ``R = 0``.

    Returns ``(servo output, V, I)``; the supply's state (charge, last current) is updated.
    """
    def at(v: float) -> tuple[Any, float]:
        out = servos.step(dt_s, goal_rad, external_nm, v)
        return out, float(out.current_a.sum()) + (extra_w / v if v > 1.0 else 0.0)

    if supply.resistance_ohm <= 0.0:
        v = supply.terminal_voltage_v()
        out, i = at(v)
    else:
        state = servos.state()
        v0 = supply.terminal_voltage_v()
        out, i0 = at(v0)
        f0 = v0 - supply.terminal_voltage_v(i0)
        v, i = v0, i0
        if abs(f0) > tol_v:
            servos.set_state(state)
            v1 = supply.terminal_voltage_v(i0)
            out, i1 = at(v1)
            f1 = v1 - supply.terminal_voltage_v(i1)
            v, i = v1, i1
            if abs(f1) > tol_v and f1 != f0:
                servos.set_state(state)
                v = v1 - f1 * (v1 - v0) / (f1 - f0)
                out, i = at(v)
        # the servos ran at v, within a few mV of the solution (the first samples, from
        # rest, converge least); the monitor reads the terminals at the current drawn
        v = supply.terminal_voltage_v(i)
    supply.draw(i, dt_s)
    return out, v, i


@dataclass(frozen=True)
class SessionRecord:
    """One ``/bench/session`` message: state change at ``t_s``."""

    t_s: float
    session_id: str
    state: str
    load_mass_kg: float
    frequency_hz: float
    duty_factor: float
    step_length_m: float
    step_height_m: float


@dataclass
class SimTrace:
    """Everything a simulator produced, as arrays sampled at the output rate.

    ``n`` samples, ``J`` joints, ``L`` legs. Measured quantities are what the sensors report
    (noise and quantisation included); ``true_*`` are the physics, for tests only.
    """

    kind: str
    joint_names: tuple[str, ...]
    leg_names: tuple[str, ...]
    t_s: FloatArray                       # (n,) true time of each sample [s]
    position_rad: FloatArray              # (n, J) measured joint angle
    velocity_rad_s: FloatArray            # (n, J)
    effort_nm: FloatArray                 # (n, J) servo torque estimate (load x stall torque)
    command_position_rad: FloatArray      # (n, J) /joint_commands
    command_velocity_rad_s: FloatArray    # (n, J)
    temperature_c: FloatArray             # (n, J) reported (integer degC)
    servo_voltage_v: FloatArray           # (n, J) reported (0.1 V)
    load_fraction: FloatArray             # (n, J) reported signed load
    servo_error: NDArray[np.uint8]        # (n, J)
    battery_voltage_v: FloatArray         # (n,) measured
    battery_current_a: FloatArray         # (n,) measured, ROS sign (negative = discharging)
    cycle_phase: FloatArray               # (n,)
    in_stance: NDArray[np.bool_]          # (n, L)
    supporting_legs: NDArray[np.int64]    # (n,)
    gait_name: FloatArray | Any           # (n,) object array of gait names
    period_s: FloatArray                  # (n,) 0 when standing
    duty_factor: FloatArray               # (n,)
    step_length_m: FloatArray             # (n,)
    step_height_m: FloatArray             # (n,)
    phase_offsets: tuple[float, ...]
    true_power_in_w: FloatArray           # (n,) power delivered at the monitor [W]
    true_mechanical_power_w: FloatArray   # (n, J) servo output power tau * w [W]
    true_temperature_c: FloatArray        # (n, J)
    speed_mps: FloatArray                 # (n,) body (or treadmill) speed
    powered: NDArray[np.bool_]            # (n,)
    ground_force_n: FloatArray | None = None   # (n,) bench normal force, measured
    tip_m: FloatArray | None = None            # (n, 3) bench leg tip, measured
    sessions: list[SessionRecord] = field(default_factory=list)
    battery_stamp_offset_s: float = 0.0   # time_offset effect
    servo_stamp_offset_s: float = 0.0     # sensor_latency effect
    effects_json: str = '{}'
    config: dict[str, Any] = field(default_factory=dict)

    @property
    def sample_count(self) -> int:
        return int(self.t_s.shape[0])

    def mean_power_in_w(self, mask: NDArray[np.bool_] | None = None) -> float:
        """Mean measured input power ``-V I`` over the samples in ``mask`` [W]."""
        p = -self.battery_voltage_v * self.battery_current_a
        return float(np.mean(p if mask is None else p[mask]))


class TraceBuilder:
    """Preallocated per-sample buffers filled by a simulator loop, turned into a SimTrace."""

    def __init__(self, n: int, joints: int, legs: int, *, bench: bool = False) -> None:
        self.n = n
        z = lambda *shape: np.zeros(shape)  # noqa: E731
        self.t_s = z(n)
        self.position_rad = z(n, joints)
        self.velocity_rad_s = z(n, joints)
        self.effort_nm = z(n, joints)
        self.command_position_rad = z(n, joints)
        self.command_velocity_rad_s = z(n, joints)
        self.temperature_c = z(n, joints)
        self.servo_voltage_v = z(n, joints)
        self.load_fraction = z(n, joints)
        self.servo_error = np.zeros((n, joints), dtype=np.uint8)
        self.battery_voltage_v = z(n)
        self.battery_current_a = z(n)
        self.cycle_phase = z(n)
        self.in_stance = np.zeros((n, legs), dtype=bool)
        self.supporting_legs = np.zeros(n, dtype=np.int64)
        self.gait_name = np.empty(n, dtype=object)
        self.period_s = z(n)
        self.duty_factor = z(n)
        self.step_length_m = z(n)
        self.step_height_m = z(n)
        self.true_power_in_w = z(n)
        self.true_mechanical_power_w = z(n, joints)
        self.true_temperature_c = z(n, joints)
        self.speed_mps = z(n)
        self.powered = np.zeros(n, dtype=bool)
        self.ground_force_n = z(n) if bench else None
        self.tip_m = z(n, 3) if bench else None

    def build(self, **kw: Any) -> SimTrace:
        names = ('t_s', 'position_rad', 'velocity_rad_s', 'effort_nm', 'command_position_rad',
                 'command_velocity_rad_s', 'temperature_c', 'servo_voltage_v', 'load_fraction',
                 'servo_error', 'battery_voltage_v', 'battery_current_a', 'cycle_phase',
                 'in_stance', 'supporting_legs', 'gait_name', 'period_s', 'duty_factor',
                 'step_length_m', 'step_height_m', 'true_power_in_w', 'true_mechanical_power_w',
                 'true_temperature_c', 'speed_mps', 'powered', 'ground_force_n', 'tip_m')
        values = {name: getattr(self, name) for name in names}
        values.update(kw)
        return SimTrace(**values)


def quantise_position(q_rad: FloatArray) -> FloatArray:
    """Round to the AX series' 0.29 degree position ticks."""
    return np.rint(q_rad / _AX_TICK_RAD) * _AX_TICK_RAD
