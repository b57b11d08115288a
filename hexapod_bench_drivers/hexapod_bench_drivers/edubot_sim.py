"""RHex-class EduBot simulator (Komsuoglu et al.): sagittal body on six compliant legs.

Core module: numpy only (the bag writer and the CLI live in :mod:`edubot_bag`, imported lazily by
:func:`write_edubot_bag` and :func:`add_cli`).

Model
-----
* **Body**: rigid, sagittal (x forward, z up), ``mass_kg`` = 3.31 kg, ``pitch_inertia_kgm2``;
  hips at ``hip_x_m`` = (+0.2, 0, -0.2) m on the body's axis through the COM. Each tripod (left
  = L1, R2, L3; right = R1, L2, R3) has one leg at each of the three hip positions.
* **Legs**: each half-circle compliant leg of arc radius ``R`` = ``leg_rest_length_m / 2`` (hip
  at one end, toe at the other) is reduced to its *virtual leg*, the spoke from the hip to the
  arc's ground point. With the shaft angle ``psi`` from the true vertical (toe behind the hip
  when positive), ``psi < 0`` is **toe contact** (spoke = chord, length ``2R`` at angle
  ``psi``, contact point fixed) and ``0 <= psi < pi`` **rolling contact** without slip (the
  contact moves ``R`` per radian; spoke ``2R cos(psi/2)`` at ``psi/2``, so the hip advances
  ``R (1 + cos psi)`` per radian, not a pinned pole's ``2R cos psi``). About that rest shape:
  a radial spring ``leg_stiffness_n_m`` (and damping) along the spoke and a bending spring
  ``leg_bending_stiffness_nm_rad`` about the hip. The hip load torque is the elastic energy's
  derivative in the shaft angle plus, while rolling, ``R`` times the horizontal hip force, so
  the motor's work equals the work on the body plus the change of elastic energy. Legs are
  massless (inertia in ``hip_inertia_kgm2``). Touch-down when the arc's lowest point reaches
  the ground; lift-off when the radial force vanishes or the arc turns off the ground.
* **Angles**: hip angle ``phi`` from the body's downward axis, positive as the legs turn (foot
  sweeping backward; clockwise seen from the right). Body pitch ``beta`` is REP-103 (about +y,
  nose-down positive), the same sense: the leg's angle from the true vertical is ``phi + beta +
  hip_zero_rad``. The Buehler clock's slow phase spans ``leg_offset +- sweep/2`` (plus
  ``hip_zero_rad``) in ``phi``.
* **Hip motors**: 11 W class brushed DC (a 25 mm 10-11 W 12 V graphite-brush motor with a
  planetary gearbox, driver peak current 5 A): winding resistance, torque constant, gear ratio
  and efficiency, viscous and Coulomb gear friction; inductance neglected (L/R about 0.1 ms).
* **Controller**: the RHex PD law in the normalised coordinates of Fig. 2 (position over pi,
  speed over ``speed_norm_rad_s``, terminal voltage over 14.8 V) with Table 1's gains times
  ``gain_scale`` (the firmware's unpublished scale to PWM units). The paper's ``phi_dot /
  (10^-3 pi)`` takes ``phi_dot`` in rad per 1 ms firmware tick: one speed unit is pi rad/s.
  The speed term is integrated backward-Euler (with the back-EMF) so stiff gains stay stable.
* **Battery**: 4S LiPo, ``battery_ocv_v`` and ``battery_resistance_ohm``; ideal H-bridges
  (regenerated power returns to the battery); electronics draw ``electronics_power_w``.
* **Foot**: Coulomb friction 0.8; beyond it the foot slides (relaxation toward the cone).
* **Integration**: semi-implicit Euler at ``dt_s`` = 1 ms; compiled with numba when installed
  (several hundred times real time), else plain Python (about 5x real time).

Constants (tags in :class:`EdubotParams`): [a] tuned against Table 3's power and speed of the
four gaits and their orderings; [b] the class of motor the paper names; [c] leg size from Table
3's travel per radian of slow-phase sweep (``2 R`` = 0.10 .. 0.11 m); [d] the paper's convention
(``phi = 0`` straight down, slow phase centred on ``+phi_0``, toe behind the hip); [e] the
driver's peak current (a lower limit gives the running gait a stalled mode); [f] scaled to the
leg size. :func:`power_breakdown` shows where the power goes.

Limitations: against Table 3, walk and pace are 10-20 % fast and running 17 % slow. Pace has
two nearby modes (24 or 28 W, by seed). A heavy hip load (``leg_damping``, ``hip_torque``) tips
running and jogging into a stalled mode: nose up, a rear leg at the current limit losing turns.
The hip effort spikes as the clock enters its fast phase; effort-onset touchdown detectors must
skip it.
Measurements and design history: docs/edubot_sim_notes.md.

Outputs are the DESIGN §4 topics as arrays: hip states at 100 Hz, battery at 100 Hz (current
negative when discharging), and the body pose from a 120 Hz motion capture in a frame that is
rotated, tilted and offset from the ground, with a clock offset and a limited tracking volume.

Named effects (``effects={'name': value}``; value 0 switches an effect off)
-------------------------------------------------------------------------
``leg_damping`` [N s/m], default off
    ``value / 3`` N s/m of radial damping per contacting leg (on top of the structural 12.9; a
    tripod acts as one SLIP leg damped by ``value``); it also resists the rolling leg's
    rotation. A plain loss up to 6 (running) / 15 (jogging); above, the stalled mode.
``hip_torque`` [N m], default off
    ``value / 3`` N m per contacting leg: a ground couple against its forward rotation that the
    motor delivers (voltage feed-forward ``R * (value/3) / (N * kt * eta)``) and the battery
    pays. From 0.3 (running) / 0.6 (jogging) a run can tip into the stalled mode.
``time_offset`` [s], default **on**, 0.025 s
    Mocap clock minus proprioception clock: a body sample at true time ``t`` is stamped
    ``t + value``.
``mocap_noise`` [m], default **on**, 0.0002 m
    White Gaussian noise std per mocap position axis (``value / 0.25 m`` rad on the
    orientation, for a marker baseline of 0.25 m).
``mocap_misalignment`` [deg], default **on**, 3 deg
    Tilt of the mocap xy-plane against the ground about a seeded horizontal axis, plus a seeded
    run yaw in [-30, 30] deg and the ground 5 to 30 mm off mocap z = 0. ``0``: mocap = ground
    frame (shifted in x and y only, so the run crosses the tracking volume).

Ground truth (``EdubotRun.truth``; also the bag's custom metadata ``edubot_truth``, JSON): each
leg's and tripod's contact intervals and the single supports (proprioception clock), the mocap
frame transform, the clock offset and the effects.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    'EDUBOT_EFFECTS',
    'EDUBOT_LEG_NAMES',
    'EdubotEffect',
    'EdubotParams',
    'EdubotRun',
    'EdubotSimError',
    'MAX_DURATION_S',
    'TABLE1_GAINS',
    'TABLE3',
    'add_cli',
    'effect_ranges',
    'power_breakdown',
    'resolve_clock',
    'resolve_effects',
    'run_summary',
    'simulate_edubot',
    'simulate_edubot_batch',
    'write_edubot_bag',
]

GRAVITY_M_S2 = 9.81
#: Longest run [s]: the robot crosses the 2 m tracking volume in seconds, and a simulated
#: second holds about 0.4 MB (1e9 s asked for 7 TiB).
MAX_DURATION_S = 600.0
EDUBOT_LEG_NAMES: tuple[str, ...] = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
_TRIPODS: dict[str, tuple[str, ...]] = {'left': ('L1', 'R2', 'L3'), 'right': ('R1', 'L2', 'R3')}
_LEG_TRIPOD = tuple('left' if leg in _TRIPODS['left'] else 'right' for leg in EDUBOT_LEG_NAMES)
# front, middle, rear hip of each leg in EDUBOT_LEG_NAMES order
_LEG_HIP_INDEX = tuple(int(leg[1]) - 1 for leg in EDUBOT_LEG_NAMES)

#: Table 1 of Komsuoglu et al.: PD gains (normalised) per gait.
TABLE1_GAINS: dict[str, tuple[float, float]] = {
    'running': (0.56, 0.03), 'jogging': (0.56, 0.03), 'pace': (0.7, 0.0), 'walk': (0.7, 0.0)}
#: Table 3 of Komsuoglu et al.: mean power [W] and speed [m/s] per gait.
TABLE3: dict[str, tuple[float, float]] = {
    'running': (31.63, 1.06), 'jogging': (42.92, 0.64), 'pace': (26.23, 0.30),
    'walk': (20.93, 0.16)}


class EdubotSimError(ValueError):
    """Bad input to the EduBot simulator (unknown gait or effect, bad duration)."""


_TABLE1_NAMES = ('running', 'jogging', 'pace', 'walk')


def resolve_clock(gait: Any) -> tuple[str, Any]:
    """(name, clock) for a Table 1 gait name or a clock object with the BuehlerClock API."""
    if not isinstance(gait, str):
        for attr in ('period_s', 'duty_factor', 'sweep_angle_rad', 'leg_offset_rad'):
            if not hasattr(gait, attr):
                raise EdubotSimError(f'gait object {gait!r} lacks {attr!r} (BuehlerClock API)')
        return 'custom', gait
    if gait not in _TABLE1_NAMES:
        raise EdubotSimError(
            f'unknown EduBot gait {gait!r}; expected one of {list(_TABLE1_NAMES)}')
    from hexapod_gait.buehler import BUEHLER_PRESETS
    return gait, BUEHLER_PRESETS[gait]


# --------------------------------------------------------------------------------------------
# Parameters and effects
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EdubotParams:
    """EduBot constants (SI units). See the module docstring for the model."""

    mass_kg: float = 3.31
    pitch_inertia_kgm2: float = 0.072        # 3.31 kg box 0.5 m x 0.1 m: m (L^2 + H^2) / 12
    hip_x_m: tuple[float, float, float] = (0.20, 0.0, -0.20)
    hip_z_m: float = 0.0                    # hips on the COM's level
    leg_rest_length_m: float = 0.105       # hip-to-toe chord = 2 R of the half circle [c]
    leg_stiffness_n_m: float = 3800.0        # per leg, radial; a tripod ~ 11 kN/m [a]
    leg_bending_stiffness_nm_rad: float = 34.0   # [a]
    leg_bending_damping_nm_s_rad: float = 0.027
    leg_radial_damping_n_s_m: float = 12.9    # structural, per leg [a]; leg_damping adds
    foot_friction: float = 0.8               # Coulomb, rubber foot on the paper's carpet
    foot_slide_stiffness_n_m: float = 2000.0  # relaxation of a slipping foot [N per m slid]
    body_half_length_m: float = 0.25         # nose/tail points that stop a fall
    body_half_height_m: float = 0.05
    # rotor through the gear (about 1.2 g cm^2 x 21.4^2 = 0.55e-4) + a 40 g half-circle leg
    # about its end (2 m R^2 = 2.2e-4 for R = 52.5 mm), at the hip [f]
    hip_inertia_kgm2: float = 2.9e-4
    hip_zero_rad: float = 0.0                # leg angle from vertical = phi + beta + zero [d]
    # motor + gearbox: a 25 mm 10-11 W 12 V graphite-brush ironless DC motor (the paper's
    # '11 W brushed DC motor'; figures of that class, not one verified datasheet row) [b]
    motor_resistance_ohm: float = 2.32
    motor_torque_constant_nm_a: float = 0.0205
    gear_ratio: float = 21.4                  # planetary, in the 20-30:1 range [a]
    motor_current_limit_a: float = 5.0        # driver's peak current limit [e]
    gear_efficiency: float = 0.67             # [a]; catalogue 2-3 stage planetary 0.6-0.8
    gear_viscous_nm_s_rad: float = 0.002
    gear_coulomb_nm: float = 0.02
    # controller
    supply_norm_v: float = 14.8              # normalised voltage 1 = 14.8 V
    speed_norm_rad_s: float = math.pi        # normalised speed = speed / this
    gain_scale: float = 6.8                  # [a]
    # battery and electronics
    battery_ocv_v: float = 15.6
    battery_resistance_ohm: float = 0.139
    electronics_power_w: float = 6.7         # PC104 stack + motor boards [a]
    # simulation and sensors
    dt_s: float = 0.001
    proprio_rate_hz: float = 100.0
    mocap_rate_hz: float = 120.0
    settle_s: float = 1.5                    # the robot enters the tracking volume after this
    initial_height_m: float = 0.105
    # permissible domain P of the paper's Fig. 3 (2 x 1 x 1 m, mocap frame): samples outside
    # it are not tracked accurately, so the simulator drops them
    mocap_volume_m: tuple[tuple[float, float], ...] = ((-1.0, 1.0), (-0.5, 0.5), (-0.5, 0.5))

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class EdubotEffect:
    """A named effect switch: unit, default (0 = off) and meaning."""

    name: str
    unit: str
    default: float
    doc: str


EDUBOT_EFFECTS: dict[str, EdubotEffect] = {e.name: e for e in (
    EdubotEffect('leg_damping', 'N s/m', 0.0,
                 'radial damping of the tripod virtual leg (value/3 per leg in contact); a '
                 'plain loss up to 6 (running) / 15 (jogging), beyond it the running and '
                 'jogging can tip into a stalled mode (a rear leg at the current limit)'),
    EdubotEffect('hip_torque', 'N m', 0.0,
                 'extra stance hip torque per tripod (value/3 per leg in contact: a ground '
                 'couple the motor delivers with a voltage feed-forward, paid from the '
                 'battery)'),
    EdubotEffect('time_offset', 's', 0.025,
                 'mocap clock minus proprioception clock'),
    EdubotEffect('mocap_noise', 'm', 0.0002,
                 'std of Gaussian noise per mocap position axis'),
    EdubotEffect('mocap_misalignment', 'deg', 3.0,
                 'tilt of the mocap xy-plane against the ground (plus seeded yaw and offset)'),
    EdubotEffect('ground_slope', 'deg', 0.0,
                 'the ground slopes down along the travel (negative: uphill); gravity has '
                 'its along-ground part and the mocap frame is levelled to gravity (its z '
                 'vertical, then tilted by mocap_misalignment)'),
)}


def effect_ranges(params: EdubotParams = EdubotParams()) -> dict[str, tuple[float, float, str]]:
    """Each effect's meaningful range ``(low, high, why)`` for the robot ``params``.

    Beyond these the run stops being the robot (review: ``hip_torque=100`` charged the battery
    from the legs, ``leg_damping=1e9`` drove the body backwards at 227 m/s).
    """
    # the hips cannot deliver more than the motor's torque at the driver's current limit
    leg_nm = (params.motor_current_limit_a * params.motor_torque_constant_nm_a
              * params.gear_ratio * params.gear_efficiency)
    return {
        'leg_damping': (0.0, 100.0, 'a plain loss up to tens of N s/m, the stalled mode beyond'),
        'hip_torque': (0.0, round(3 * leg_nm, 2),
                       f'3 stance legs x {leg_nm:.3g} N m, the hip torque at the driver\'s '
                       f'{params.motor_current_limit_a:g} A current limit'),
        'time_offset': (-1e5, 1e5, 'about a day: no clock offset of one recording'),
        'mocap_noise': (0.0, 0.1, 'a larger noise is no motion capture'),
        'mocap_misalignment': (0.0, 45.0, 'a tilt of the mocap plane against the ground'),
        'ground_slope': (-10.0, 10.0, 'a steeper slope is no level-ground gait'),
    }


def resolve_effects(effects: Mapping[str, float] | None,
                    params: EdubotParams = EdubotParams()) -> dict[str, float]:
    """Every effect's value: the defaults overridden by ``effects``; unknown names and values
    out of :func:`effect_ranges` refused."""
    out = {name: eff.default for name, eff in EDUBOT_EFFECTS.items()}
    ranges = effect_ranges(params)
    for name, value in (effects or {}).items():
        if name not in EDUBOT_EFFECTS:
            raise EdubotSimError(
                f'unknown EduBot effect {name!r}; expected one of {sorted(EDUBOT_EFFECTS)}')
        value = float(value)
        if not math.isfinite(value) or (value < 0 and name not in ('time_offset',
                                                                     'ground_slope')):
            raise EdubotSimError(f'effect {name!r} must be a finite value >= 0, got {value!r}')
        lo, hi, why = ranges.get(name, (-math.inf, math.inf, ''))
        if not lo <= value <= hi:
            unit = EDUBOT_EFFECTS[name].unit
            raise EdubotSimError(f'effect {name!r} = {value:g} {unit} is out of range: expected '
                                 f'{lo:g} to {hi:g} {unit} ({why})')
        out[name] = value
    return out


# --------------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EdubotRun:
    """One simulated run. Proprioceptive arrays share ``t_s`` (100 Hz, robot clock).

    Attributes
    ----------
    gait : str
        Table 1 name or ``'custom'``.
    clock : BuehlerClock
        The clock the hips were driven to (``period_s``, ``duty_factor``, ``sweep_angle_rad``,
        ``leg_offset_rad``).
    leg_names : tuple of str
        ``('L1', 'L2', 'L3', 'R1', 'R2', 'R3')``; joints are ``<leg>_hip``.
    t_s : (n,) float
        Proprioception sample times [s].
    hip_position_rad, hip_velocity_rad_s, hip_effort_nm : (n, 6) float
        Measured hip angle (unwrapped) [rad], speed [rad/s], output torque [N m].
    target_position_rad, target_velocity_rad_s : (n, 6) float
        Buehler-clock targets.
    battery_voltage_v, battery_current_a : (n,) float
        Terminal voltage [V] and current [A] (ROS sign: negative when discharging), each the
        mean over the preceding sample interval.
    body_x_m, body_z_m, body_pitch_rad, body_vx_m_s, body_vz_m_s : (n,) float
        True COM position / velocity in the ground frame [m, m/s]; pitch per REP-103 [rad].
    mocap_t_s : (m,) float
        Mocap stamps [s] in the mocap clock (= true time + clock offset); only samples inside
        the tracking volume.
    mocap_position_m : (m, 3) float
        COM position in the mocap frame [m].
    mocap_quat_xyzw : (m, 4) float
        Body orientation in the mocap frame.
    fine_t_s : (k,) float
        Simulation-step times (1 kHz) for the fine truth below.
    fine_state : (k, 5) float
        True [x, vx, z, vz, pitch] of the COM in the ground frame at ``fine_t_s``.
    fine_contact : (k, 6) bool
        Each leg in contact at ``fine_t_s``.
    effects : dict
        Every effect's value (0 = off).
    truth : dict
        JSON-able ground truth (see the module docstring).
    """

    gait: str
    clock: Any
    params: EdubotParams
    seed: int
    leg_names: tuple[str, ...]
    t_s: np.ndarray
    hip_position_rad: np.ndarray
    hip_velocity_rad_s: np.ndarray
    hip_effort_nm: np.ndarray
    target_position_rad: np.ndarray
    target_velocity_rad_s: np.ndarray
    battery_voltage_v: np.ndarray
    battery_current_a: np.ndarray
    body_x_m: np.ndarray
    body_z_m: np.ndarray
    body_pitch_rad: np.ndarray
    body_vx_m_s: np.ndarray
    body_vz_m_s: np.ndarray
    mocap_t_s: np.ndarray
    mocap_position_m: np.ndarray
    mocap_quat_xyzw: np.ndarray
    fine_t_s: np.ndarray
    fine_state: np.ndarray
    fine_contact: np.ndarray
    effects: dict[str, float]
    truth: dict[str, Any] = field(repr=False)

    @property
    def duration_s(self) -> float:
        return float(self.fine_t_s[-1] + self.params.dt_s)

    @property
    def power_w(self) -> np.ndarray:
        """(n,) battery input power [W] = -voltage * current."""
        return -self.battery_voltage_v * self.battery_current_a


def run_summary(run: EdubotRun, *, t0_s: float | None = None,
                t1_s: float | None = None) -> dict[str, float]:
    """Mean input power [W], mean forward speed [m/s] and specific resistance over a window.

    The window defaults to the steady part of the run: from ``params.settle_s`` to the end.
    """
    t0 = run.params.settle_s if t0_s is None else t0_s
    t1 = run.t_s[-1] if t1_s is None else t1_s
    sel = (run.t_s >= t0) & (run.t_s <= t1)
    if sel.sum() < 2:
        raise EdubotSimError(f'window {t0}..{t1} s holds fewer than 2 samples')
    power = float(run.power_w[sel].mean())
    ts = run.t_s[sel]
    speed = float((run.body_x_m[sel][-1] - run.body_x_m[sel][0]) / (ts[-1] - ts[0]))
    sr = power / (run.params.mass_kg * GRAVITY_M_S2 * speed) if speed > 0 else math.inf
    return {'power_w': power, 'speed_m_s': speed, 'specific_resistance': sr}


def power_breakdown(run: EdubotRun, *, t0_s: float | None = None,
                    t1_s: float | None = None) -> dict[str, float]:
    """Where the input watts go, mean over a window (default: settle to the end) [W].

    Estimated from the 100 Hz samples (instantaneous hip torque and speed, so the means are
    unbiased but carry sampling noise): the motor current is recovered from the output torque
    through the gear efficiency (``tau_out = k N I eta`` when driving, ``/ eta`` when driven).

    Returns
    -------
    dict
        ``input_w`` (battery), ``electronics_w``, ``copper_w`` (sum of I^2 R over the six
        motors), ``hip_mechanical_w`` (net sum of output torque x hip speed, negative when the
        legs are driven back), ``gear_and_friction_w`` (electrical power into the motors minus
        copper minus hip mechanical), ``battery_internal_w`` (I^2 R_bat, not in ``input_w``),
        ``current_limited_fraction`` (share of motor samples at the driver's current limit) and
        ``mean_abs_lag_rad`` (clock target minus measured hip angle).
    """
    p = run.params
    t0 = p.settle_s if t0_s is None else t0_s
    t1 = run.t_s[-1] if t1_s is None else t1_s
    sel = (run.t_s >= t0) & (run.t_s <= t1)
    if sel.sum() < 2:
        raise EdubotSimError(f'window {t0}..{t1} s holds fewer than 2 samples')
    tau = run.hip_effort_nm[sel]
    w = run.hip_velocity_rad_s[sel]
    k_out = p.motor_torque_constant_nm_a * p.gear_ratio
    eta = p.gear_efficiency
    tau_m = np.where(tau * w >= 0.0, tau / eta, tau * eta)
    cur = tau_m / k_out
    copper = float((cur ** 2 * p.motor_resistance_ohm).sum(axis=1).mean())
    mech = float((tau * w).sum(axis=1).mean())
    p_in = float(run.power_w[sel].mean())
    i_bat = -run.battery_current_a[sel]
    return {
        'input_w': p_in,
        'electronics_w': p.electronics_power_w,
        'copper_w': copper,
        'hip_mechanical_w': mech,
        'gear_and_friction_w': p_in - p.electronics_power_w - copper - mech,
        'battery_internal_w': float((i_bat ** 2 * p.battery_resistance_ohm).mean()),
        'current_limited_fraction': float(
            np.mean(np.abs(cur) >= 0.999 * p.motor_current_limit_a)),
        'mean_abs_lag_rad': float(np.mean(np.abs(
            run.target_position_rad[sel] - run.hip_position_rad[sel]))),
    }


# --------------------------------------------------------------------------------------------
# Physics
# --------------------------------------------------------------------------------------------
def _gains(name: str, clock: Any) -> tuple[float, float]:
    if name in TABLE1_GAINS:
        return TABLE1_GAINS[name]
    kp = float(getattr(clock, 'kp_norm', 0.0) or TABLE1_GAINS['running'][0])
    return kp, float(getattr(clock, 'kd_norm', 0.0))


def _integrate(clock: Any, gains: tuple[float, float], p: EdubotParams, n_steps: int,
               damping: float, hip_torque: float, init_vx: float, ocv: float,
               *, compiled: bool = True, slope_deg: float = 0.0) -> dict[str, np.ndarray]:
    """Fixed-step semi-implicit Euler integration of one run; per-step arrays.

    The step loop (:func:`_kernel`) is compiled with numba when it is installed (and
    ``compiled``), else it runs as plain Python (the benchmark's baseline).
    """
    dt = p.dt_s
    t = np.arange(n_steps) * dt
    tri = {name: (clock.target_angle(t, name), clock.target_speed(t, name))
           for name in ('left', 'right')}
    tgt = np.ascontiguousarray(np.stack([tri[_LEG_TRIPOD[i]][0] for i in range(6)], axis=1))
    tgt_v = np.ascontiguousarray(np.stack([tri[_LEG_TRIPOD[i]][1] for i in range(6)], axis=1))
    hxs = np.array([p.hip_x_m[j] for j in _LEG_HIP_INDEX], dtype=float)
    kp, kd = gains
    k_out = p.motor_torque_constant_nm_a * p.gear_ratio       # N m/A and V s/rad at the hip
    consts = np.array([
        dt, p.hip_z_m,
        p.gain_scale * kp / math.pi * p.supply_norm_v,          # volts per rad
        p.gain_scale * kd / p.speed_norm_rad_s * p.supply_norm_v,
        p.leg_rest_length_m, p.leg_stiffness_n_m,
        p.leg_bending_stiffness_nm_rad, p.leg_bending_damping_nm_s_rad,
        p.motor_resistance_ohm, k_out, p.gear_efficiency,
        p.leg_radial_damping_n_s_m + damping / 3.0,             # per leg in contact
        p.motor_resistance_ohm * hip_torque / 3.0 / (k_out * p.gear_efficiency),
        p.gear_viscous_nm_s_rad, p.gear_coulomb_nm, p.motor_current_limit_a,
        p.mass_kg, p.pitch_inertia_kgm2, p.hip_inertia_kgm2, p.hip_zero_rad,
        GRAVITY_M_S2 * math.cos(math.radians(slope_deg)),            # into the ground
        p.body_half_length_m, p.body_half_height_m, p.foot_friction,
        1.0 / p.foot_slide_stiffness_n_m, p.electronics_power_w, p.battery_resistance_ohm,
        p.initial_height_m, float(init_vx), float(ocv),
        hip_torque / 3.0,                                        # stance couple per leg
        GRAVITY_M_S2 * math.sin(math.radians(slope_deg))], dtype=float)  # along the ground
    out_state = np.empty((n_steps, 5))
    out_phi = np.empty((n_steps, 6))
    out_dphi = np.empty((n_steps, 6))
    out_tau = np.empty((n_steps, 6))
    out_vi = np.empty((n_steps, 2))
    out_contact = np.zeros((n_steps, 6), dtype=np.bool_)
    out_gap = np.empty((n_steps, 6))
    kernel = _compiled_kernel() if compiled else _kernel
    n_slip = kernel(tgt, tgt_v, hxs, consts, out_state, out_phi, out_dphi, out_tau, out_vi,
                    out_contact, out_gap)
    return {
        't': t, 'target': tgt, 'target_v': tgt_v, 'state': out_state, 'phi': out_phi,
        'dphi': out_dphi, 'tau': out_tau, 'vbat': out_vi[:, 0], 'ibat': out_vi[:, 1],
        'contact': out_contact, 'gap': out_gap, 'slip_steps': np.array(n_slip),
    }


_KERNEL_CACHE: list[Any] = []


def _compiled_kernel() -> Any:
    """:func:`_kernel` compiled by numba (cached on disk), or the Python one without numba."""
    if not _KERNEL_CACHE:
        try:
            import numba
            _KERNEL_CACHE.append(numba.njit(cache=True, fastmath=False)(_kernel))
        except ImportError:  # pragma: no cover - numba is optional
            _KERNEL_CACHE.append(_kernel)
    return _KERNEL_CACHE[0]


def _kernel(tgt: np.ndarray, tgt_v: np.ndarray, hxs: np.ndarray, c: np.ndarray,
            out_state: np.ndarray, out_phi: np.ndarray, out_dphi: np.ndarray,
            out_tau: np.ndarray, out_vi: np.ndarray, out_contact: np.ndarray,
            out_gap: np.ndarray) -> int:
    """The step loop (numba-compatible: scalars, math and numpy arrays only)."""
    n_steps = tgt.shape[0]
    dt, hz, kpn, kdn, r0, kr, kb, cbend = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    rm, k_out, eta, c_leg, v_ff, visc, coul, i_max = (c[8], c[9], c[10], c[11], c[12], c[13],
                                                      c[14], c[15])
    m, inertia, jh, zero, g = c[16], c[17], c[18], c[19], c[20]
    body_hl, body_hh, mu, slide_gain, p_elec, r_bat = c[21], c[22], c[23], c[24], c[25], c[26]
    two_pi = 2.0 * math.pi
    # body-ground safety contact (nose, tail): stiff penalty spring with viscous friction
    kg, cg, cf = 2.0e4, 150.0, 50.0
    n_slip = 0
    x, z, beta, vx, vz, wb = 0.0, c[27], 0.0, c[28], 0.0, 0.0
    ocv = c[29]
    ff_couple = c[30]
    g_along = c[31]
    v_bat = ocv
    phi = np.empty(6)
    dphi = np.zeros(6)
    contact = np.zeros(6, dtype=np.bool_)
    armed = np.ones(6, dtype=np.bool_)
    foot = np.zeros(6)
    tau_out = np.zeros(6)
    gap = np.zeros(6)
    ddphi_l = np.zeros(6)
    roll_rate = np.zeros(6)
    r_arc = 0.5 * r0
    for i in range(6):
        phi[i] = tgt[0, i]
    for k in range(n_steps):
        cb = math.cos(beta)
        sb = math.sin(beta)
        fx_sum = 0.0
        fz_sum = 0.0
        torque_cw = 0.0
        p_drv = 0.0
        for i in range(6):
            hx = hxs[i]
            rx = hx * cb + hz * sb
            rz = hz * cb - hx * sb
            hip_x = x + rx
            hip_z = z + rz
            hvx = vx + wb * rz
            hvz = vz - wb * rx
            psi = phi[i] + beta + zero
            psi_w = psi - two_pi * math.floor(psi / two_pi + 0.5)
            # rest shape of the virtual leg (hip -> lowest point of the arc) at this shaft
            # angle: toe contact (pole of length 2R) while the toe is ahead of the hip,
            # rolling on the arc (length 2R cos(psi/2) at angle psi/2) once it is behind
            rolling = 0.0 <= psi_w < math.pi
            if rolling:
                c_half = math.cos(0.5 * psi_w)
                s_half = math.sin(0.5 * psi_w)
                rest_l = r0 * c_half
                rest_th = 0.5 * psi_w
                d_rest_l = -r_arc * s_half
                d_rest_th = 0.5
                low_z = hip_z - r0 * c_half * c_half       # hip_z - R (1 + cos psi)
            else:
                rest_l = r0
                rest_th = psi_w
                d_rest_l = 0.0
                d_rest_th = 1.0
                cp = math.cos(psi_w)
                low_z = hip_z - r0 * cp if cp > 0.0 else 1.0
            dx = 0.0
            ll = 1.0
            if contact[i]:
                dx = hip_x - foot[i]
                ll = math.sqrt(dx * dx + hip_z * hip_z)
                # lift-off: the radial force has vanished (the leg is back at its rest
                # shape) or the arc has turned off the ground
                if ll >= rest_l or hip_z <= 0.0 or low_z > 0.5:
                    contact[i] = False
            if not contact[i]:
                if low_z > 0.002:
                    armed[i] = True
                if armed[i] and low_z <= 0.0:
                    contact[i] = True
                    armed[i] = False
                    foot[i] = hip_x - rest_l * math.sin(rest_th)
                    dx = hip_x - foot[i]
                    ll = math.sqrt(dx * dx + hip_z * hip_z)
                else:
                    gap[i] = low_z
            tau_leg = 0.0
            roll_rate[i] = 0.0
            if contact[i]:
                gap[i] = ll - rest_l
                inv_l = 1.0 / ll
                w_abs = dphi[i] + wb
                ldot = (dx * hvx + hip_z * hvz) * inv_l
                f_r = kr * (rest_l - ll) - c_leg * (ldot - d_rest_l * w_abs)
                if f_r < 0.0:
                    f_r = 0.0
                psi_g = math.atan2(dx, hip_z)
                dpsi_g = (hip_z * hvx - dx * hvz) * inv_l * inv_l
                tau_b = kb * (rest_th - psi_g) + cbend * (d_rest_th * w_abs - dpsi_g)
                f_t = tau_b * inv_l
                gx = (f_r * dx + f_t * hip_z) * inv_l
                gz = (f_r * hip_z - f_t * dx) * inv_l
                lim = mu * gz if gz > 0.0 else 0.0
                if gx > lim or gx < -lim:
                    # Coulomb slip: the traction is capped and the foot slides so as to
                    # relax the leg back toward the friction cone.
                    excess = (gx - lim) if gx > 0.0 else (gx + lim)
                    foot[i] -= excess * slide_gain
                    n_slip += 1
                    gx = lim if gx > 0.0 else -lim
                fx_sum += gx
                fz_sum += gz
                torque_cw += rz * gx - rx * gz
                # load on the shaft = d(leg energy)/d(shaft angle) plus, while rolling,
                # the work of the hip force as the contact point rolls forward R per rad
                tau_leg = tau_b * d_rest_th + f_r * d_rest_l
                if rolling:
                    tau_leg += r_arc * gx
                    roll_rate[i] = r_arc * w_abs
                # hip_torque: the ground's constant couple on the stance leg against its
                # forward rotation
                # (an extra stance load the hip must deliver, reacted on the body through
                # the motor like the rest of the hip torque)
                tau_leg += ff_couple
            # hip motor under PD to the clock
            w = dphi[i]
            u0 = kpn * (tgt[k, i] - phi[i]) + kdn * tgt_v[k, i]
            if contact[i]:
                # hip_torque's feed-forward: the couple's stall-equivalent voltage, so the
                # loop keeps tracking its clock while the motor delivers the extra torque
                u0 += v_ff
            # the speed term -kdn * w and the back-EMF are taken at the end of the step
            # (backward Euler on the motor's electrical damping): the firmware's normalised
            # speed gain is far stiffer than an explicit 1 ms step can follow
            coul_w = coul * math.tanh(w * 20.0)
            # gear efficiency: eta when the motor drives the leg, 1/eta when it is driven
            e_g = eta
            for _ in range(2):
                w_new = (jh * w / dt + e_g * k_out * u0 / rm - coul_w - tau_leg) / (
                    jh / dt + e_g * k_out * (kdn + k_out) / rm + visc)
                u = u0 - kdn * w_new
                cur = (u - k_out * w_new) / rm
                if cur * w >= 0.0:
                    break
                e_g = 1.0 / eta
            if u > v_bat or u < -v_bat:
                u = v_bat if u > 0.0 else -v_bat
                cur = (u - k_out * w) / rm
            if cur > i_max or cur < -i_max:
                # the driver's current limit lowers the applied voltage
                cur = i_max if cur > 0.0 else -i_max
                u = rm * cur + k_out * w
            tau_m = k_out * cur
            to = tau_m * eta if tau_m * w >= 0.0 else tau_m / eta
            tau_out[i] = to
            tau_net = to - visc * w - coul_w
            torque_cw -= tau_net
            ddphi_l[i] = tau_net - tau_leg
            p_drv += u * cur
        for side in range(2):
            bx_b = body_hl if side == 0 else -body_hl
            rx = bx_b * cb - body_hh * sb
            rz = -body_hh * cb - bx_b * sb
            pz = z + rz
            if pz < 0.0:
                pvx = vx + wb * rz
                pvz = vz - wb * rx
                fn = -kg * pz - cg * pvz
                if fn > 0.0:
                    ft = -cf * pvx
                    if ft > fn:
                        ft = fn
                    elif ft < -fn:
                        ft = -fn
                    fx_sum += ft
                    fz_sum += fn
                    torque_cw += rz * ft - rx * fn
        ab = torque_cw / inertia
        i_bat = (p_drv + p_elec) / v_bat
        out_state[k, 0] = x
        out_state[k, 1] = vx
        out_state[k, 2] = z
        out_state[k, 3] = vz
        out_state[k, 4] = beta
        for i in range(6):
            out_phi[k, i] = phi[i]
            out_dphi[k, i] = dphi[i]
            out_tau[k, i] = tau_out[i]
            out_contact[k, i] = contact[i]
            out_gap[k, i] = gap[i]
        out_vi[k, 0] = v_bat
        out_vi[k, 1] = i_bat
        vx += (fx_sum / m + g_along) * dt
        vz += (fz_sum / m - g) * dt
        wb += ab * dt
        x += vx * dt
        z += vz * dt
        beta += wb * dt
        for i in range(6):
            dphi[i] += (ddphi_l[i] / jh - ab) * dt
            phi[i] += dphi[i] * dt
            foot[i] += roll_rate[i] * dt
        v_bat = ocv - r_bat * i_bat
    return n_slip


# --------------------------------------------------------------------------------------------
# Truth: contact intervals from the per-step contact flags and the gap signal
# --------------------------------------------------------------------------------------------
def _intervals(flag: np.ndarray, gap: np.ndarray | None, t: np.ndarray) -> np.ndarray:
    """(m, 2) [start, end) intervals where ``flag`` is true; edges refined on ``gap``'s zero."""
    f = flag.astype(np.int8)
    d = np.diff(f)
    starts = list(np.nonzero(d == 1)[0] + 1)
    ends = list(np.nonzero(d == -1)[0] + 1)
    if f[0]:
        starts.insert(0, 0)
    if f[-1]:
        ends.append(len(f))
    out = []
    for s, e in zip(starts, ends):
        ts = _crossing(gap, t, s) if gap is not None and s > 0 else t[s]
        te = _crossing(gap, t, e) if gap is not None and e < len(f) else \
            (t[e] if e < len(f) else t[-1] + (t[1] - t[0]))
        out.append((ts, te))
    return np.array(out, dtype=float).reshape(-1, 2)


def _crossing(gap: np.ndarray, t: np.ndarray, i: int) -> float:
    """Zero crossing of ``gap`` between samples i-1 and i (linear), clipped to that step."""
    g0, g1 = gap[i - 1], gap[i]
    if g0 == g1 or np.sign(g0) == np.sign(g1):
        return float(t[i])
    frac = g0 / (g0 - g1)
    return float(t[i - 1] + min(max(frac, 0.0), 1.0) * (t[i] - t[i - 1]))


def _interval_ops(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Intervals where boolean step array ``a`` is true and ``b`` false."""
    return _intervals(a & ~b, None, t)


# --------------------------------------------------------------------------------------------
# Motion capture
# --------------------------------------------------------------------------------------------
def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    if axis == 'x':
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 'y':
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _quat_from_matrix(rm: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) quaternions xyzw (w >= 0)."""
    m = np.asarray(rm)
    w = np.sqrt(np.maximum(0.0, 1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2])) / 2
    x = np.sqrt(np.maximum(0.0, 1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2])) / 2
    y = np.sqrt(np.maximum(0.0, 1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2])) / 2
    zq = np.sqrt(np.maximum(0.0, 1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2])) / 2
    x = np.copysign(x, m[..., 2, 1] - m[..., 1, 2])
    y = np.copysign(y, m[..., 0, 2] - m[..., 2, 0])
    zq = np.copysign(zq, m[..., 1, 0] - m[..., 0, 1])
    q = np.stack([x, y, zq, w], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _mocap(p: EdubotParams, eff: dict[str, float], rng: np.random.Generator,
           t_fine: np.ndarray, state: np.ndarray, x_settle: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    tilt_deg = eff['mocap_misalignment']
    if tilt_deg > 0:
        yaw = math.radians(rng.uniform(-30.0, 30.0))
        axis_az = rng.uniform(0.0, 2 * math.pi)
        z0 = rng.uniform(0.005, 0.030)
    else:
        yaw, axis_az, z0 = 0.0, 0.0, 0.0
    tilt = math.radians(tilt_deg)
    # tilt about the horizontal axis (cos az, sin az, 0): Rz(az) Rx(tilt) Rz(-az)
    r_tilt = _rot('z', axis_az) @ _rot('x', tilt) @ _rot('z', -axis_az)
    # a sloped ground under a mocap levelled to gravity: the ground turned about its y axis
    rot = r_tilt @ _rot('z', yaw) @ _rot('y', math.radians(eff.get('ground_slope', 0.0)))
    (bx0, bx1), (by0, by1), _ = p.mocap_volume_m
    half_len = 0.5 * min((bx1 - bx0) / max(abs(math.cos(yaw)), 1e-9),
                         (by1 - by0) / max(abs(math.sin(yaw)), 1e-9))
    centre = np.array([0.5 * (bx0 + bx1), 0.5 * (by0 + by1), z0])
    # the volume lies ahead along the travel after the settling: behind the start for a robot
    # walking backwards (a clock turning the hips the other way)
    travel = 1.0 if state[-1, 0] >= x_settle else -1.0
    x_c = x_settle + travel * half_len
    offset = centre - rot @ np.array([x_c, 0.0, 0.0])
    # mocap sampling in its own clock
    toff = eff['time_offset']
    dt_m = 1.0 / p.mocap_rate_hz
    t_end = t_fine[-1]
    phase0 = rng.uniform(0.0, dt_m)
    t_true = np.arange(phase0, t_end, dt_m)
    xs = np.interp(t_true, t_fine, state[:, 0])
    zs = np.interp(t_true, t_fine, state[:, 2])
    bs = np.interp(t_true, t_fine, state[:, 4])
    pos_g = np.stack([xs, np.zeros_like(xs), zs], axis=1)
    pos_m = pos_g @ rot.T + offset
    cb, sb = np.cos(bs), np.sin(bs)
    r_body = np.zeros((len(bs), 3, 3))                # rotation about +y by pitch (REP-103)
    r_body[:, 0, 0] = cb
    r_body[:, 0, 2] = sb
    r_body[:, 1, 1] = 1.0
    r_body[:, 2, 0] = -sb
    r_body[:, 2, 2] = cb
    noise = eff['mocap_noise']
    if noise > 0:
        pos_m = pos_m + rng.normal(0.0, noise, pos_m.shape)
        ang = rng.normal(0.0, noise / 0.25, (len(bs), 3))
        r_noise = np.stack([_rodrigues(a) for a in ang]) if len(bs) else r_body
        r_body = r_noise @ r_body
    quat = _quat_from_matrix(rot @ r_body)
    lo = np.array([v[0] for v in p.mocap_volume_m])
    hi = np.array([v[1] for v in p.mocap_volume_m])
    inside = np.all((pos_m >= lo) & (pos_m <= hi), axis=1)
    frame = {
        'mocap_from_ground_rotation': rot.tolist(),
        'mocap_from_ground_translation_m': offset.tolist(),
        'yaw_deg': math.degrees(yaw),
        'tilt_deg': tilt_deg,
        'tilt_axis_azimuth_deg': math.degrees(axis_az),
        'ground_plane_z_m': float(z0),
        'volume_m': [list(v) for v in p.mocap_volume_m],
        # the same box in the fields of slip_identification.preprocess.Box
        'permissible_box': {'lower_m': lo.tolist(), 'upper_m': hi.tolist()},
        'volume_centre_ground_x_m': float(x_c),
    }
    return t_true[inside] + toff, pos_m[inside], quat[inside], frame


def _rodrigues(a: np.ndarray) -> np.ndarray:
    th = float(np.linalg.norm(a))
    if th < 1e-15:
        return np.eye(3)
    k = a / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * kx + (1 - math.cos(th)) * (kx @ kx)


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------
def simulate_edubot_batch(gait: Any, *, duration_s: float,
                          effects: Mapping[str, float] | None = None,
                          seeds: list[int] | tuple[int, ...] = (0,),
                          params: EdubotParams = EdubotParams()) -> list[EdubotRun]:
    """Simulate one run per seed in one vectorised integration (same gait and effects).

    Each seed varies the initial forward speed (+-10 %), the battery's open-circuit voltage
    (+-0.2 V), the mocap frame placement and the mocap noise: the seed changes the physics,
    not only the noise (the first two pick the mode of a gait that has two, e.g. the pace's 24
    or 28 W).
    """
    name, clock = resolve_clock(gait)
    eff = resolve_effects(effects, params)
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s)
            and duration_s > 0):
        raise EdubotSimError(f'duration_s must be a positive number, got {duration_s!r}')
    if duration_s > MAX_DURATION_S:
        raise EdubotSimError(f'duration_s {duration_s:g} s is more than {MAX_DURATION_S:g} s '
                             '(one run through the motion-capture volume)')
    if duration_s * params.proprio_rate_hz < 2:
        raise EdubotSimError(f'duration_s {duration_s:g} s holds fewer than 2 samples at '
                             f'{params.proprio_rate_hz:g} Hz')
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise EdubotSimError('seeds must not be empty')
    rngs = [np.random.default_rng(s) for s in seeds]
    n_steps = int(round(duration_s / params.dt_s))
    v_nominal = TABLE3.get(name, (0.0, 0.5))[1]
    init_vx = np.array([v_nominal * (1 + 0.1 * r.uniform(-1, 1)) for r in rngs])
    ocv = np.array([params.battery_ocv_v + 0.2 * r.uniform(-1, 1) for r in rngs])
    gains = _gains(name, clock)
    raws = [_integrate(clock, gains, params, n_steps, eff['leg_damping'], eff['hip_torque'],
                       float(v0), float(e0), slope_deg=eff['ground_slope'])
            for v0, e0 in zip(init_vx, ocv)]
    return [_assemble(name, clock, params, eff, seed, rng, raw)
            for raw, seed, rng in zip(raws, seeds, rngs)]


def simulate_edubot(gait: Any, *, duration_s: float,
                    effects: Mapping[str, float] | None = None, seed: int = 0,
                    params: EdubotParams = EdubotParams()) -> EdubotRun:
    """Simulate one EduBot run of ``duration_s`` seconds.

    Parameters
    ----------
    gait
        ``'running'``, ``'jogging'``, ``'pace'`` or ``'walk'`` (Table 1), or a clock object
        with the ``hexapod_gait.buehler.BuehlerClock`` API (PD gains then from its ``kp``,
        ``kd`` attributes if present, else the running gains).
    duration_s
        Simulated time [s]; the robot starts at rest height with about its gait's speed and
        enters the tracking volume ``params.settle_s`` later.
    effects
        ``{name: value}`` for :data:`EDUBOT_EFFECTS`; 0 switches an effect off.
    seed
        Same seed, same data. It draws the physics too (the battery's open-circuit voltage
        and the initial speed, see :func:`simulate_edubot_batch`), not only the noise.
    """
    return simulate_edubot_batch(gait, duration_s=duration_s, effects=effects, seeds=(seed,),
                                 params=params)[0]


def _assemble(name: str, clock: Any, p: EdubotParams, eff: dict[str, float], seed: int,
              rng: np.random.Generator, raw: dict[str, np.ndarray]) -> EdubotRun:
    t_fine = raw['t']
    n_steps = len(t_fine)
    stride = int(round(1.0 / (p.proprio_rate_hz * p.dt_s)))
    idx = np.arange(0, n_steps, stride)
    state = raw['state']
    vbat = raw['vbat']
    ibat = raw['ibat']
    # battery: mean over the preceding interval (first sample: its own step)
    csum_v = np.concatenate([[0.0], np.cumsum(vbat)])
    csum_i = np.concatenate([[0.0], np.cumsum(ibat)])
    lo = np.maximum(idx - stride + 1, 0)
    cnt = idx - lo + 1
    v_mean = (csum_v[idx + 1] - csum_v[lo]) / cnt
    i_mean = (csum_i[idx + 1] - csum_i[lo]) / cnt
    contact = raw['contact']
    gap = raw['gap']
    x_settle = float(np.interp(p.settle_s, t_fine, state[:, 0]))
    m_t, m_pos, m_quat, frame = _mocap(p, eff, rng, t_fine, state, x_settle)
    # truth
    leg_contact = {leg: _intervals(contact[:, i], gap[:, i], t_fine)
                   for i, leg in enumerate(EDUBOT_LEG_NAMES)}
    tri_mask = {tr: np.array([_LEG_TRIPOD[i] == tr for i in range(6)]) for tr in _TRIPODS}
    tri_on = {tr: contact[:, tri_mask[tr]].any(axis=1) for tr in _TRIPODS}
    tripod_contact = {tr: _intervals(tri_on[tr], None, t_fine) for tr in _TRIPODS}
    single = {tr: _interval_ops(tri_on[tr], tri_on['right' if tr == 'left' else 'left'],
                                t_fine) for tr in _TRIPODS}
    # refine tripod edges with the legs' interpolated events
    leg_events = np.sort(np.concatenate([leg_contact[leg].ravel() for leg in leg_contact]))
    tripod_contact = {tr: _snap(v, leg_events, p.dt_s) for tr, v in tripod_contact.items()}
    single = {tr: _snap(v, leg_events, p.dt_s) for tr, v in single.items()}
    clock_d = {a: float(getattr(clock, a)) for a in
               ('period_s', 'duty_factor', 'sweep_angle_rad', 'leg_offset_rad')}
    truth: dict[str, Any] = {
        'gait': name,
        'clock': clock_d,
        'gains_kp_kd': list(_gains(name, clock)),
        'seed': seed,
        'duration_s': n_steps * p.dt_s,
        'time_base': 'proprioception clock [s]; mocap stamps = true time + clock_offset_s',
        'clock_offset_s': eff['time_offset'],
        'effects': dict(eff),
        'frame': frame,
        'settle_s': p.settle_s,
        'leg_contact': {k: v.tolist() for k, v in leg_contact.items()},
        'tripod_contact': {k: v.tolist() for k, v in tripod_contact.items()},
        'single_support': {k: v.tolist() for k, v in single.items()},
        'tripod_legs': {k: list(v) for k, v in _TRIPODS.items()},
        'params': p.to_dict(),
    }
    run = EdubotRun(
        gait=name, clock=clock, params=p, seed=seed, leg_names=EDUBOT_LEG_NAMES,
        t_s=t_fine[idx].copy(),
        hip_position_rad=raw['phi'][idx].copy(),
        hip_velocity_rad_s=raw['dphi'][idx].copy(),
        hip_effort_nm=raw['tau'][idx].copy(),
        target_position_rad=raw['target'][idx].copy(),
        target_velocity_rad_s=raw['target_v'][idx].copy(),
        battery_voltage_v=v_mean, battery_current_a=-i_mean,
        body_x_m=state[idx, 0].copy(), body_z_m=state[idx, 2].copy(),
        body_pitch_rad=state[idx, 4].copy(), body_vx_m_s=state[idx, 1].copy(),
        body_vz_m_s=state[idx, 3].copy(),
        mocap_t_s=m_t, mocap_position_m=m_pos, mocap_quat_xyzw=m_quat,
        fine_t_s=t_fine, fine_state=state.copy(), fine_contact=contact.copy(),
        effects=dict(eff), truth=truth)
    summ = run_summary(run) if run.t_s[-1] > p.settle_s + 0.1 else {}
    truth['summary'] = summ
    return run


def _snap(intervals: np.ndarray, events: np.ndarray, dt: float) -> np.ndarray:
    """Replace step-resolution edges by the nearest interpolated leg event within one step."""
    if intervals.size == 0 or events.size == 0:
        return intervals
    out = intervals.copy()
    for j in range(out.shape[0]):
        for c in range(2):
            i = np.searchsorted(events, out[j, c])
            cands = events[max(i - 1, 0):i + 1]
            if cands.size:
                best = cands[np.argmin(np.abs(cands - out[j, c]))]
                if abs(best - out[j, c]) <= dt:
                    out[j, c] = best
    return out


def write_edubot_bag(path: str | Path, gait: Any, *, duration_s: float,
                     effects: Mapping[str, float] | None = None, seed: int = 0,
                     storage: str = 'mcap', params: EdubotParams = EdubotParams()) -> Path:
    """Simulate and write the run into a rosbag2 bag (see :mod:`edubot_bag`)."""
    from hexapod_bench_drivers.edubot_bag import write_edubot_bag as _write
    return _write(path, gait, duration_s=duration_s, effects=effects, seed=seed,
                  storage=storage, params=params)


def add_cli(subparsers: Any) -> None:
    """Register the ``edubot`` subcommand of ``hexapod-sim`` (see :mod:`edubot_bag`)."""
    from hexapod_bench_drivers.edubot_bag import add_cli as _add
    _add(subparsers)
