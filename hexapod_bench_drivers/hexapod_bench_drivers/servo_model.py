"""Electromechanical model of a Dynamixel-class servo (DC motor, gearbox, P controller, heat).

Core module: numpy only, no ROS. One :class:`ServoModel` simulates ``count`` identical servos at
once (arrays of shape ``(count,)``), so a whole robot steps in one call.

Physics, all quantities referred to the OUTPUT shaft (after the gearbox):

* **Motor and gear from the datasheet points.** With supply voltage ``V``, stall torque
  ``tau_s`` at stall current ``I_s`` and no-load speed ``w_nl``:

  - winding resistance ``R = V / (I_s - I_standby)`` (the controller's standby current is part
    of the datasheet's stall current);
  - effective torque constant ``k_t = tau_s / (I_s - I_standby)`` [N m/A];
  - back-EMF constant ``k_e = (V - R i_nl) / w_nl`` [V s/rad] with the no-load current
    ``i_nl = (c + b w_nl) / k_t`` that overcomes the gear's Coulomb ``c`` and viscous ``b``
    friction;
  - gear efficiency ``eta = k_t / k_e`` (0.93 for the AX-18A, whose calibrated constant Coulomb
    friction takes most of the gear loss), modelled as a load-dependent Coulomb friction
    ``(1 - eta) |k_e i|`` in the gear: the gearbox passes ``eta k_e i`` when the motor drives
    the load, the load must supply ``(2 - eta) k_e i`` to back-drive it, and at standstill the
    gear holds any torque inside that band (stiction).

* **Electrical.** Inductance is neglected (L/R is about 0.1 ms): ``i = (u V - k_e w) / R(T)``
  where ``u`` in [-1, 1] is the PWM duty. The servo draws ``I_standby + max(u i, 0)`` from the
  supply: the controller's electronics (basal power) plus the bridge's averaged current; braking
  energy is dissipated in the bridge, not returned to the supply (no regeneration).

* **Position controller** as the AX series' compliance: the potentiometer on the output shaft
  measures ``q_out``; ``u = sign(e) max(|e| - margin, 0) / slope`` clipped to the torque limit,
  with ``e = goal - q_out``. Finite stiffness means a static error under load.

* **Compliance and backlash** between the motor side ``q_m`` and the output:
  ``q_out = q_m + tau_ext / k_struct + (backlash / 2) tanh(tau_ext / tau_bl)``.

* **Mechanics.** ``J w' = k_e i + tau_ext - (c + (1 - eta) |k_e i|) sgn(w) - b w`` with ``J``
  the rotor inertia times the gear ratio squared plus any load inertia; Karnopp stick-slip
  friction (the shaft sticks while the static torque stays inside the friction band, or inside
  ``static_friction_ratio`` times it: stiction, 1 by default), or,
  with ``friction_smoothing_rad_s > 0``, a dithered friction that grows linearly with speed
  below that speed (no sticking: a static load is then held by the motor alone);
  semi-implicit Euler in sub-steps.

* **Heat.** One first-order winding node: ``C dT/dt = i^2 R(T) - (T - T_amb) / R_th`` with
  ``tau_th = R_th C`` of minutes, copper resistance ``R(T) = R_ref (1 + 0.00393 (T - T_ref))``
  and magnet flux ``k_e(T) = k_e,ref (1 - 0.0035 (T - T_ref))``, so a hot servo needs more
  current for the same torque (about +1 W per leg after 10 min at 3 Hz with 500 g, as Brodoline
  et al. measured).

* **Reporting as the servo does:** integer degC, the present load as the signed PWM fraction
  (that is what AX/MX firmware reports), voltage in 0.1 V. The true supply current is returned
  separately for the simulated power monitor, and the signed winding current ``i`` (the motor
  current an X-series servo's current sensor reports in Present Current: positive when the motor
  drives in the positive direction, negative while it brakes a load that back-drives it) as
  ``winding_current_a``.

* **Loss breakdown** (``record_losses=True``): every step also returns the power of each term
  (standby, copper, bridge braking, Coulomb, gear, viscous, rotor kinetic energy, load), which
  sum to the supply power; ``bench/bench_sim_breakdown.py`` prints it per gait phase and joint.

Calibration: with the default constants the simulated AntBot reproduces Brodoline et al.'s
whole-robot figures (standing power, power and efficiency at 0.6 m/s, CoT/M, thermal rise;
``bench/bench_sim_breakdown.py --budget``). Limitation: it does not reproduce two of their gait
findings (duty factor 0.7 and the wave gait cost more than the beta 0.5 tripod, not less).
``friction_smoothing_rad_s`` defaults to 0: smoothing keeps the whole-robot figures but makes
the bench-fitted energy model over-predict the slow robot.
Measurements and design history: docs/servo_model_notes.md.

Sign convention: ``external_torque_nm`` is the torque the outside world applies ON the output
shaft, positive in the joint's positive direction (gravity pulling a joint down gives a negative
external torque for a joint whose positive direction lifts it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _servo_kernel

__all__ = [
    'COPPER_TEMP_COEFF_PER_K',
    'ERROR_INPUT_VOLTAGE',
    'ERROR_OVERHEATING',
    'ERROR_OVERLOAD',
    'ServoModel',
    'ServoOutput',
    'ServoParams',
    'ServoParamsError',
]

#: Temperature coefficient of copper resistance [1/K] (0.393 %/K).
COPPER_TEMP_COEFF_PER_K = 0.00393

#: Dynamixel Protocol 1.0 error bits (status packet ``error`` byte).
ERROR_INPUT_VOLTAGE = 0x01
ERROR_OVERHEATING = 0x04
ERROR_OVERLOAD = 0x20

_RPM = 2.0 * math.pi / 60.0
_DEG = math.pi / 180.0

FloatArray = NDArray[np.float64]


class ServoParamsError(ValueError):
    """A servo parameter is out of its physical range (names the field and the range)."""


@dataclass(frozen=True)
class ServoParams:
    """Datasheet and tuning constants of one servo type. Build with the model constructors.

    Attributes
    ----------
    model : str
        Model name, for example ``'AX-18A'``.
    gear_ratio : float
        Motor turns per output turn.
    rated_voltage_v : float
        Voltage of the datasheet points [V].
    stall_torque_nm, stall_current_a : float
        Stall point at ``rated_voltage_v`` [N m], [A].
    no_load_speed_rad_s : float
        Output speed without load at ``rated_voltage_v`` [rad/s].
    standby_current_a : float
        Controller electronics current, drawn whenever the servo is powered [A].
    rotor_inertia_kgm2 : float
        Motor rotor (and first gear) inertia on the motor side [kg m^2].
    coulomb_friction_nm, viscous_friction_nm_s : float
        Gear friction at the output [N m], [N m s/rad].
    stick_speed_rad_s : float
        Speed below which the shaft may stick (Karnopp friction band) [rad/s].
    friction_smoothing_rad_s : float
        0 (default): Karnopp stick-slip, a loaded shaft at rest stays anywhere inside the static
        friction band, so after a touchdown the gear friction carries up to ``c + (1 - eta)
        |k_e i|`` of the load and the motor holds only the rest. > 0: no sticking; below this
        output speed the Coulomb and gear friction grow linearly with speed (a dithered
        friction: the vibration of a walking robot and the PWM ripple keep a loaded joint
        creeping until the motor carries the whole static load). Implicit in the linear
        region, so any value is stable.
    static_friction_ratio : float
        Breakaway over sliding friction of the gear, >= 1 (1, the default: one level). With
        Karnopp friction (``friction_smoothing_rad_s = 0``) a shaft at rest stays stuck while
        its static torque stays inside ``ratio (c + (1 - eta) |k_e i|)`` and slides against the
        sliding band ``c + (1 - eta) |k_e i|`` once it breaks away (stiction; ignored with
        friction smoothing). A what-if, not calibrated: docs/servo_model_notes.md.
    compliance_slope_rad, compliance_margin_rad : float
        P controller: full PWM at ``slope`` beyond the dead band ``margin`` [rad].
    structural_stiffness_nm_rad : float
        Gear and horn stiffness between motor side and output [N m/rad].
    backlash_rad : float
        Total gear backlash [rad].
    backlash_torque_nm : float
        Torque over which the backlash is taken up [N m].
    thermal_resistance_k_w : float
        Winding to ambient thermal resistance [K/W].
    thermal_time_constant_s : float
        Winding thermal time constant [s].
    reference_temperature_c : float
        Temperature at which the datasheet resistance and constants hold [degC].
    copper_temp_coeff_per_k : float
        Relative change of the winding resistance per kelvin (copper: +0.393 %/K).
    magnet_temp_coeff_per_k : float
        Relative change of the motor constant (magnet flux) per kelvin (ferrite and bonded
        magnets: -0.2 to -0.35 %/K; -0.35 %/K calibrated to the paper's thermal drift): a hot
        motor needs more current for the same torque.
    temperature_limit_c : float
        Overheating shutdown threshold [degC].
    min_voltage_v, max_voltage_v : float
        Input voltage window; outside it the input-voltage error bit is set [V].
    position_min_rad, position_max_rad : float
        Mechanical range of the output [rad].
    """

    model: str
    gear_ratio: float
    rated_voltage_v: float
    stall_torque_nm: float
    stall_current_a: float
    no_load_speed_rad_s: float
    standby_current_a: float
    # Rotor inertia and gear friction are not on the datasheets: calibrated so that an AntBot of
    # 18 AX-18A reproduces Brodoline et al.'s whole-robot figures (standing ~11 W, ~65 W at
    # 0.6 m/s, CoT/M ~37 J/(m kg) at 0.84 m/s); the no-load current is then ~0.5 A.
    rotor_inertia_kgm2: float = 1.2e-8
    coulomb_friction_nm: float = 0.24
    viscous_friction_nm_s: float = 0.02
    stick_speed_rad_s: float = 1e-3
    friction_smoothing_rad_s: float = 0.0
    static_friction_ratio: float = 1.0
    compliance_slope_rad: float = 32 * 0.29 * _DEG
    compliance_margin_rad: float = 1 * 0.29 * _DEG
    structural_stiffness_nm_rad: float = 60.0
    backlash_rad: float = 0.4 * _DEG
    backlash_torque_nm: float = 0.02
    thermal_resistance_k_w: float = 18.0
    thermal_time_constant_s: float = 480.0
    reference_temperature_c: float = 25.0
    temperature_limit_c: float = 75.0
    min_voltage_v: float = 9.0
    max_voltage_v: float = 12.6
    position_min_rad: float = -150.0 * _DEG
    position_max_rad: float = 150.0 * _DEG
    copper_temp_coeff_per_k: float = field(default=COPPER_TEMP_COEFF_PER_K)
    magnet_temp_coeff_per_k: float = -0.0035

    def __post_init__(self) -> None:
        positive = ('gear_ratio', 'rated_voltage_v', 'stall_torque_nm', 'stall_current_a',
                    'no_load_speed_rad_s', 'rotor_inertia_kgm2', 'stick_speed_rad_s',
                    'compliance_slope_rad', 'structural_stiffness_nm_rad',
                    'backlash_torque_nm', 'thermal_resistance_k_w', 'thermal_time_constant_s')
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ServoParamsError(f'ServoParams.{name} = {value!r}: expected a finite '
                                       'value > 0')
        for name in ('standby_current_a', 'coulomb_friction_nm', 'viscous_friction_nm_s',
                     'compliance_margin_rad', 'backlash_rad', 'friction_smoothing_rad_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ServoParamsError(f'ServoParams.{name} = {value!r}: expected a finite '
                                       'value >= 0')
        if not (math.isfinite(self.static_friction_ratio) and self.static_friction_ratio >= 1.0):
            raise ServoParamsError(
                f'ServoParams.static_friction_ratio = {self.static_friction_ratio!r}: expected a '
                'finite value >= 1')
        if self.standby_current_a >= self.stall_current_a:
            raise ServoParamsError(
                f'ServoParams.standby_current_a = {self.standby_current_a!r}: expected less '
                f'than stall_current_a = {self.stall_current_a!r}')
        if not 0.0 < self.gear_efficiency <= 1.0:
            raise ServoParamsError(
                f'ServoParams of {self.model}: derived gear efficiency {self.gear_efficiency:.3f}'
                ' is outside (0, 1]; check stall torque, stall current and no-load speed')

    # --- derived motor constants -------------------------------------------------------------
    @property
    def motor_current_stall_a(self) -> float:
        """Winding current at stall [A] (datasheet stall current minus standby)."""
        return self.stall_current_a - self.standby_current_a

    @property
    def winding_resistance_ohm(self) -> float:
        """Winding (plus bridge) resistance at ``reference_temperature_c`` [ohm]."""
        return self.rated_voltage_v / self.motor_current_stall_a

    @property
    def torque_constant_nm_a(self) -> float:
        """Effective output torque per winding ampere when driving, gear losses included."""
        return self.stall_torque_nm / self.motor_current_stall_a

    @property
    def no_load_current_a(self) -> float:
        """Winding current that overcomes the gear friction at no-load speed [A]."""
        w = self.no_load_speed_rad_s
        return (self.coulomb_friction_nm + self.viscous_friction_nm_s * w) \
            / self.torque_constant_nm_a

    @property
    def back_emf_constant_v_s(self) -> float:
        """Back-EMF per output rad/s [V s/rad] (equals the loss-free torque constant)."""
        r_i = self.winding_resistance_ohm * self.no_load_current_a
        return (self.rated_voltage_v - r_i) / self.no_load_speed_rad_s

    @property
    def gear_efficiency(self) -> float:
        """Gearbox efficiency ``k_t / k_e`` (0..1)."""
        return self.torque_constant_nm_a / self.back_emf_constant_v_s

    @property
    def reflected_inertia_kgm2(self) -> float:
        """Rotor inertia seen at the output [kg m^2]."""
        return self.rotor_inertia_kgm2 * self.gear_ratio ** 2

    @property
    def thermal_capacity_j_k(self) -> float:
        """Winding heat capacity [J/K]."""
        return self.thermal_time_constant_s / self.thermal_resistance_k_w

    def with_changes(self, **changes: Any) -> ServoParams:
        """Copy with some fields replaced (validated again)."""
        return replace(self, **changes)

    # --- datasheet presets ---------------------------------------------------------------------
    @classmethod
    def ax18a(cls) -> ServoParams:
        """Dynamixel AX-18A: 254:1, stall 1.8 N m at 2.2 A and 12 V, 97 rpm, standby 50 mA."""
        return cls(model='AX-18A', gear_ratio=254.0, rated_voltage_v=12.0, stall_torque_nm=1.8,
                   stall_current_a=2.2, no_load_speed_rad_s=97.0 * _RPM,
                   standby_current_a=0.05)

    @classmethod
    def ax12a(cls) -> ServoParams:
        """Dynamixel AX-12A: 254:1, stall 1.5 N m at 1.5 A and 12 V, 59 rpm, standby 50 mA."""
        return cls(model='AX-12A', gear_ratio=254.0, rated_voltage_v=12.0, stall_torque_nm=1.5,
                   stall_current_a=1.5, no_load_speed_rad_s=59.0 * _RPM,
                   standby_current_a=0.05)

    @classmethod
    def xl430(cls) -> ServoParams:
        """Dynamixel XL430-W250: 258.5:1, stall 1.5 N m at 1.4 A and 12 V, 61 rpm, 52 mA.

        Protocol 2.0 servo with a 360 degree magnetic encoder.
        """
        return cls(model='XL430-W250', gear_ratio=258.5, rated_voltage_v=12.0,
                   stall_torque_nm=1.5, stall_current_a=1.4, no_load_speed_rad_s=61.0 * _RPM,
                   standby_current_a=0.052,
                   compliance_slope_rad=0.15, compliance_margin_rad=0.0,
                   max_voltage_v=14.8, min_voltage_v=6.5, temperature_limit_c=72.0,
                   position_min_rad=-math.pi, position_max_rad=math.pi)

    @classmethod
    def xm430(cls) -> ServoParams:
        """Dynamixel XM430-W350: 353.5:1, stall 4.1 N m at 2.3 A and 12 V, 46 rpm, 40 mA."""
        return cls(model='XM430-W350', gear_ratio=353.5, rated_voltage_v=12.0,
                   stall_torque_nm=4.1, stall_current_a=2.3, no_load_speed_rad_s=46.0 * _RPM,
                   standby_current_a=0.04, rotor_inertia_kgm2=1.0e-7,
                   coulomb_friction_nm=0.04, viscous_friction_nm_s=0.004,
                   compliance_slope_rad=0.12, compliance_margin_rad=0.0,
                   structural_stiffness_nm_rad=150.0, thermal_resistance_k_w=12.0,
                   thermal_time_constant_s=600.0, max_voltage_v=14.8, min_voltage_v=10.0,
                   temperature_limit_c=80.0, position_min_rad=-math.pi,
                   position_max_rad=math.pi)

    @classmethod
    def by_name(cls, name: str) -> ServoParams:
        """Preset by model name (``ax18a``, ``ax12a``, ``xl430``, ``xm430``, case-insensitive)."""
        key = name.lower().replace('-', '').replace('_', '')
        presets = {'ax18a': cls.ax18a, 'ax12a': cls.ax12a, 'xl430': cls.xl430,
                   'xl430w250': cls.xl430, 'xm430': cls.xm430, 'xm430w350': cls.xm430}
        if key not in presets:
            raise ServoParamsError(f'servo model {name!r}: expected one of ax18a, ax12a, xl430, '
                                   'xm430')
        return presets[key]()


@dataclass(frozen=True)
class ServoOutput:
    """Result of one :meth:`ServoModel.step`; every array has shape ``(count,)``.

    ``position_rad`` and ``velocity_rad_s`` are at the end of the step; the currents and powers
    are means over the step, so ``sum(power_w * dt)`` is the energy drawn.

    Attributes
    ----------
    position_rad : output shaft angle as the potentiometer measures it [rad]
    velocity_rad_s : output speed [rad/s]
    torque_nm : torque the servo horn applies to its load [N m] (``-external_torque_nm`` while
        the servo drives or holds; the rotor's own inertia is inside the servo)
    current_a : supply current of each servo, electronics included [A] (mean; the real servo
        cannot measure it)
    temperature_c : true winding temperature [degC]
    load_fraction : signed PWM duty as the servo reports its present load (-1..1)
    power_w : supply power of each servo [W] (mean)
    mechanical_power_w : power delivered to the load ``-external_torque * velocity`` [W] (mean)
    winding_loss_w : Joule loss in the winding [W] (mean)
    reported_temperature_c : integer degC as the servo reports it
    reported_voltage_v : supply voltage with 0.1 V resolution
    error : Dynamixel error bits (uint8)
    torque_enabled : whether each servo drives its motor
    winding_current_a : signed motor (winding) current ``i`` [A] (mean; 0 with torque off):
        the torque-like current an X-series servo reports in Present Current, its sign that
        of the motor's torque ``k_e i`` (positive driving the positive direction, negative
        braking a load that back-drives the shaft the positive way), electronics excluded;
        unlike ``load_fraction`` (the PWM duty), it carries no back-EMF term
    losses : power breakdown [W] (means over the step, shape ``(count,)``) when the model was
        built with ``record_losses=True``, else None. Keys: ``standby`` (electronics),
        ``extra`` (effects), ``copper`` (``i^2 R``), ``coulomb`` (``c |w|``), ``gear``
        (load-dependent gear friction ``(1 - eta) |k_e i| |w|``), ``viscous`` (``b w^2``),
        ``kinetic`` (rate of change of the rotor's kinetic energy), ``load`` (power into the
        load, ``mechanical_power_w``, carried load inertia included), ``brake`` (power the
        bridge dissipates while the motor generates, ``max(-u i, 0) V``). ``standby + extra +
        copper + brake + coulomb + gear + viscous + kinetic + load`` equals ``power_w`` up to
        the integrator's own dissipation (about 1 % over a gait cycle at 3.3 ms sub-steps).
    """

    position_rad: FloatArray
    velocity_rad_s: FloatArray
    torque_nm: FloatArray
    current_a: FloatArray
    temperature_c: FloatArray
    load_fraction: FloatArray
    power_w: FloatArray
    mechanical_power_w: FloatArray
    winding_loss_w: FloatArray
    reported_temperature_c: NDArray[np.int64]
    reported_voltage_v: FloatArray
    error: NDArray[np.uint8]
    torque_enabled: NDArray[np.bool_]
    winding_current_a: FloatArray
    losses: dict[str, FloatArray] | None = None


def _floats(x: ArrayLike, n: int) -> FloatArray:
    """A contiguous float64 array of length ``n`` (a scalar broadcast), for the kernel."""
    if type(x) is np.ndarray and x.shape == (n,) and x.dtype == np.float64 \
            and x.flags.c_contiguous:
        return x
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=np.float64), (n,)))


def _as_count(value: ArrayLike, count: int, name: str) -> FloatArray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(count, float(arr))
    if arr.shape != (count,):
        raise ServoParamsError(f'{name}: expected a scalar or shape ({count},), got shape '
                               f'{arr.shape}')
    return arr.astype(float, copy=True)


class ServoModel:
    """``count`` identical servos stepped together.

    Parameters
    ----------
    params : ServoParams, optional
        Servo type; AX-18A by default.
    count : int
        Number of servos (arrays of shape ``(count,)``).
    initial_position_rad : float or (count,)
        Start angle; the servos start at rest, holding this angle.
    initial_temperature_c : float or (count,)
        Winding temperature at start [degC].
    ambient_temperature_c : float
        Air temperature [degC].
    load_inertia_kgm2 : float or (count,)
        Extra inertia rigidly on the output [kg m^2] (0 when the caller puts the load's inertia
        into ``external_torque_nm`` through inverse dynamics).
    extra_power_w : float or (count,)
        Constant extra supply power per powered servo [W] (effect ``basal_power`` or
        ``leg_anomaly``).
    thermal_drift_w_k : float
        Extra supply power per kelvin of winding temperature above ambient [W/K] (effect
        ``thermal_drift``), on top of the copper resistance rise that is always modelled.
    extra_friction_nm : float or (count,)
        Extra Coulomb friction at the output [N m] (a stiff joint).
    max_substep_s : float
        Longest integration sub-step [s]; 1 ms is accurate, 2 ms is still stable.
    torque_enabled : bool or (count,)
        Initial torque enable.
    record_losses : bool
        Fill :attr:`ServoOutput.losses` with the power breakdown (diagnostics; a little slower).
    """

    def __init__(self, params: ServoParams | None = None, *, count: int = 1,
                 initial_position_rad: ArrayLike = 0.0,
                 initial_temperature_c: ArrayLike = 26.0,
                 ambient_temperature_c: float = 26.0,
                 load_inertia_kgm2: ArrayLike = 0.0,
                 extra_power_w: ArrayLike = 0.0,
                 thermal_drift_w_k: float = 0.0,
                 extra_friction_nm: ArrayLike = 0.0,
                 max_substep_s: float = 1e-3,
                 torque_enabled: ArrayLike = True,
                 record_losses: bool = False) -> None:
        if count < 1:
            raise ServoParamsError(f'count = {count!r}: expected at least 1 servo')
        if not max_substep_s > 0.0:
            raise ServoParamsError(f'max_substep_s = {max_substep_s!r}: expected > 0')
        self.params = params if params is not None else ServoParams.ax18a()
        self.count = int(count)
        p = self.params
        self.ambient_temperature_c = float(ambient_temperature_c)
        self.max_substep_s = float(max_substep_s)
        self.record_losses = bool(record_losses)
        self.thermal_drift_w_k = float(thermal_drift_w_k)
        self.extra_power_w = _as_count(extra_power_w, count, 'extra_power_w')
        self.extra_friction_nm = _as_count(extra_friction_nm, count, 'extra_friction_nm')
        self.inertia_kgm2 = p.reflected_inertia_kgm2 + _as_count(load_inertia_kgm2, count,
                                                                 'load_inertia_kgm2')
        self.motor_position_rad = _as_count(initial_position_rad, count, 'initial_position_rad')
        self.velocity_rad_s = np.zeros(count)
        self.temperature_c = _as_count(initial_temperature_c, count, 'initial_temperature_c')
        self.torque_enabled = np.broadcast_to(np.asarray(torque_enabled, dtype=bool),
                                              (count,)).copy()
        #: Goal-speed limit [rad/s] per servo (0 = no limit, as the AX ``moving speed`` 0).
        self.moving_speed_rad_s = np.zeros(count)
        #: Maximum PWM duty per servo (AX ``torque limit``, 0..1).
        self.torque_limit = np.ones(count)
        self._setpoint_rad = self.motor_position_rad.copy()
        self._last_external_nm = np.zeros(count)
        self._overheated = np.zeros(count, dtype=bool)
        self._ke = p.back_emf_constant_v_s
        self._eta = p.gear_efficiency
        self._r_ref = p.winding_resistance_ohm
        self._kp = 1.0 / p.compliance_slope_rad
        if self.compiled:
            _servo_kernel.warm()   # its first call loads numba's cache (0.6 s): now, not mid-run

    # --- state access ---------------------------------------------------------------------------
    def output_position_rad(self, external_torque_nm: ArrayLike | None = None) -> FloatArray:
        """Output angle as measured, for the given (or last) external torque [rad]."""
        tau = self._last_external_nm if external_torque_nm is None \
            else _as_count(external_torque_nm, self.count, 'external_torque_nm')
        return self.motor_position_rad + self._deflection(tau)

    def winding_resistance_ohm(self) -> FloatArray:
        """Present winding resistance of each servo (copper temperature coefficient) [ohm]."""
        p = self.params
        return self._r_ref * (1.0 + p.copper_temp_coeff_per_k
                              * (self.temperature_c - p.reference_temperature_c))

    def reset_overheating(self) -> None:
        """Clear the latched overheating shutdown (as a reboot of the servo)."""
        self._overheated[:] = False

    def _deflection(self, tau_ext: FloatArray) -> FloatArray:
        p = self.params
        out: FloatArray = tau_ext / p.structural_stiffness_nm_rad
        if p.backlash_rad > 0.0:
            out = out + 0.5 * p.backlash_rad * np.tanh(tau_ext / p.backlash_torque_nm)
        return out

    #: the sub-step loop compiled with numba when installed (False: the numpy loop, the
    #: reference the compiled one is tested against)
    compiled = True

    _STATE = ('motor_position_rad', 'velocity_rad_s', 'temperature_c', '_setpoint_rad',
              '_last_external_nm', '_overheated')

    def state(self) -> dict[str, FloatArray]:
        """Copy of everything :meth:`step` changes (to step again from the same state)."""
        return {k: np.array(getattr(self, k), copy=True) for k in self._STATE}

    def set_state(self, state: dict[str, FloatArray]) -> None:
        """Restore a :meth:`state` copy."""
        for k in self._STATE:
            setattr(self, k, np.array(state[k], copy=True))

    # --- integration ----------------------------------------------------------------------------
    def _step_compiled(self, dt_s: float, n_sub: int, goal: FloatArray, tau_ext: FloatArray,
                       volts: FloatArray) -> ServoOutput:
        """:meth:`step` after its input checks, compiled (:func:`_servo_kernel.step_all`:
        the numpy code below, per servo, to the bit)."""
        p = self.params
        n = self.count
        prm = np.array([
            p.temperature_limit_c, self._r_ref,
            p.copper_temp_coeff_per_k, p.reference_temperature_c, self._ke,
            p.magnet_temp_coeff_per_k, self._kp, p.compliance_margin_rad,
            p.coulomb_friction_nm, p.viscous_friction_nm_s, p.stick_speed_rad_s,
            1.0 - self._eta, p.friction_smoothing_rad_s, p.reflected_inertia_kgm2,
            p.standby_current_a, self.ambient_temperature_c, self.thermal_drift_w_k,
            math.exp(-dt_s / p.thermal_time_constant_s), p.thermal_resistance_k_w,
            p.min_voltage_v, p.max_voltage_v, p.static_friction_ratio], dtype=float)
        deflection = _floats(self._deflection(tau_ext), n)
        q = np.array(self.motor_position_rad, dtype=float)
        w = np.array(self.velocity_rad_s, dtype=float)
        temp = np.array(self.temperature_c, dtype=float)
        setpoint = np.array(self._setpoint_rad, dtype=float)
        out = np.empty((11, n))
        flags = np.empty((3, n), dtype=np.int64)
        rec = self.record_losses
        losses = np.empty((9, n))
        _servo_kernel.step_all(
            float(dt_s), n_sub, _floats(goal, n), _floats(tau_ext, n), _floats(volts, n),
            deflection, q, w, temp, setpoint, self._overheated, self.torque_enabled,
            _floats(self.torque_limit, n), _floats(self.moving_speed_rad_s, n),
            _floats(self.extra_friction_nm, n), _floats(self.extra_power_w, n),
            _floats(self.inertia_kgm2, n), prm, rec, out, flags, losses)
        self.motor_position_rad, self.velocity_rad_s = q, w
        self.temperature_c, self._setpoint_rad = temp, setpoint
        drive = flags[2] == 1
        return ServoOutput(
            position_rad=out[0], velocity_rad_s=out[1], torque_nm=out[2], current_a=out[3],
            temperature_c=out[4], load_fraction=out[5], power_w=out[6],
            mechanical_power_w=out[7], winding_loss_w=out[8],
            reported_temperature_c=flags[0].copy(), reported_voltage_v=out[9],
            error=flags[1].astype(np.uint8), torque_enabled=drive, winding_current_a=out[10],
            losses=dict(zip(('standby', 'extra', 'copper', 'coulomb', 'gear', 'viscous',
                             'kinetic', 'load', 'brake'), losses)) if rec else None)

    def step(self, dt_s: float, goal_position_rad: ArrayLike,
             external_torque_nm: ArrayLike = 0.0,
             supply_voltage_v: ArrayLike = 12.0) -> ServoOutput:
        """Advance all servos by ``dt_s`` seconds.

        Parameters
        ----------
        dt_s : float
            Step length [s] (> 0); split into sub-steps of at most ``max_substep_s``.
        goal_position_rad : float or (count,)
            Goal angle of each servo [rad], clipped to the mechanical range.
        external_torque_nm : float or (count,)
            Torque the load applies on each output shaft [N m], held over the step.
        supply_voltage_v : float or (count,)
            Voltage at the servos' terminals [V]; below 1 V the servo is unpowered.

        Returns
        -------
        ServoOutput
        """
        if not (dt_s > 0.0 and math.isfinite(dt_s)):
            raise ServoParamsError(f'dt_s = {dt_s!r}: expected a finite step > 0 s')
        p = self.params
        n = self.count
        goal = np.clip(_as_count(goal_position_rad, n, 'goal_position_rad'),
                       p.position_min_rad, p.position_max_rad)
        tau_ext = _as_count(external_torque_nm, n, 'external_torque_nm')
        volts = _as_count(supply_voltage_v, n, 'supply_voltage_v')
        if not (np.all(np.isfinite(goal)) and np.all(np.isfinite(tau_ext))
                and np.all(np.isfinite(volts))):
            raise ServoParamsError('step(): goal_position_rad, external_torque_nm and '
                                   'supply_voltage_v must be finite')
        self._last_external_nm = tau_ext
        n_sub = max(1, math.ceil(dt_s / self.max_substep_s - 1e-9))
        if self.compiled and _servo_kernel.HAVE_NUMBA:
            return self._step_compiled(dt_s, n_sub, goal, tau_ext, volts)
        powered = volts >= 1.0
        self._overheated |= self.temperature_c > p.temperature_limit_c
        drive = self.torque_enabled & powered & ~self._overheated
        h = dt_s / n_sub

        resistance = self.winding_resistance_ohm()
        deflection = self._deflection(tau_ext)
        umax = np.where(drive, np.clip(self.torque_limit, 0.0, 1.0), 0.0)
        neg_umax = -umax
        ke = self._ke * (1.0 + p.magnet_temp_coeff_per_k
                         * (self.temperature_c - p.reference_temperature_c))
        kp, margin = self._kp, p.compliance_margin_rad
        coulomb = p.coulomb_friction_nm + self.extra_friction_nm
        visc, w_eps, mu = p.viscous_friction_nm_s, p.stick_speed_rad_s, 1.0 - self._eta
        w_s = p.friction_smoothing_rad_s
        ratio_s = p.static_friction_ratio
        no_stick = np.zeros(n, dtype=bool)
        h_inv_j = h / self.inertia_kgm2
        # Plain ufuncs only in the sub-step loop: it is the simulators' hot path.
        volt_over_r = volts / resistance
        ke_over_r = ke / resistance
        drive_f = drive.astype(float)
        all_drive = bool(drive.all())
        speed_limit = self.moving_speed_rad_s
        limited = speed_limit > 0.0
        any_limited = bool(np.any(limited))
        setpoint = self._setpoint_rad
        q0 = self.motor_position_rad
        q = q0.copy()
        w0 = self.velocity_rad_s
        w = w0.copy()
        sum_bridge = np.zeros(n)
        sum_i2 = np.zeros(n)
        sum_i = np.zeros(n)
        u = np.zeros(n)
        absolute, maximum, minimum, where, sign = (np.absolute, np.maximum, np.minimum,
                                                   np.where, np.sign)
        rec = self.record_losses
        if rec:
            sum_coulomb, sum_gear, sum_visc, sum_brake = (np.zeros(n) for _ in range(4))
        for _ in range(n_sub):
            if any_limited:
                dq = np.clip(goal - setpoint, -speed_limit * h, speed_limit * h)
                setpoint = where(limited, setpoint + dq, goal)
            else:
                setpoint = goal
            err = setpoint - q - deflection
            u = np.copysign(maximum(absolute(err) - margin, 0.0) * kp, err)
            u = minimum(maximum(u, neg_umax), umax)
            i = u * volt_over_r - ke_over_r * w
            if not all_drive:
                i *= drive_f
            gen = ke * i
            # Karnopp friction: load-dependent Coulomb (gear loss) plus constant Coulomb; the
            # shaft sticks while the static torque stays inside the friction band.
            f_max = coulomb + mu * absolute(gen)
            tau_free = gen + tau_ext - visc * w
            if w_s > 0.0:
                # dithered friction: linear in speed below w_s (implicit), Coulomb above
                w_lin = (w + h_inv_j * tau_free) / (1.0 + h_inv_j * f_max / w_s)
                w_new = w + h_inv_j * (tau_free - f_max * sign(w_lin))
                w_new = where((absolute(w_lin) <= w_s) | (w_new * w_lin < 0.0),
                              np.clip(w_lin, -w_s, w_s), w_new)
                stick = no_stick
            else:
                moving = absolute(w) > w_eps
                direction = sign(where(moving, w, tau_free))
                w_new = w + h_inv_j * (tau_free - f_max * direction)
                # stick: at rest inside the friction band, or crossing zero speed in this step
                f_static = f_max if ratio_s == 1.0 else ratio_s * f_max
                stick = where(moving, w_new * w < 0.0, absolute(tau_free) <= f_static)
            if rec:
                # the sub-step's displacement is h * w_new (semi-implicit Euler)
                w_abs = absolute(where(stick, 0.0, w_new))
                f_frac = minimum(w_abs / w_s, 1.0) if w_s > 0.0 else 1.0
                sum_coulomb += coulomb * f_frac * w_abs
                sum_gear += mu * absolute(gen) * f_frac * w_abs
                sum_visc += visc * absolute(w) * w_abs
                sum_brake += maximum(-u * i, 0.0)
            w = where(stick, 0.0, w_new)
            q += h * w
            sum_bridge += maximum(u * i, 0.0)
            sum_i2 += i * i
            sum_i += i
        # Power into the load: work of the load torque plus the kinetic energy of any load
        # inertia carried on the output (the rotor's own kinetic energy stays in the servo).
        load_j = self.inertia_kgm2 - p.reflected_inertia_kgm2
        sum_pmech = (-tau_ext * (q - q0) + 0.5 * load_j * (w * w - self.velocity_rad_s ** 2)) / h
        self._setpoint_rad = np.array(setpoint, dtype=float)
        self.motor_position_rad = q
        self.velocity_rad_s = w

        mean_bridge_a = sum_bridge / n_sub
        winding_loss_w = sum_i2 / n_sub * resistance
        rise_k = self.temperature_c - self.ambient_temperature_c
        extra_w = np.where(powered, self.extra_power_w + self.thermal_drift_w_k
                           * np.maximum(rise_k, 0.0), 0.0)
        safe_v = np.where(powered, volts, 1.0)
        current_a = np.where(powered, p.standby_current_a + mean_bridge_a + extra_w / safe_v, 0.0)
        power_w = current_a * volts

        # Exact exponential update of the first-order winding node over the step.
        decay = math.exp(-dt_s / p.thermal_time_constant_s)
        t_inf = self.ambient_temperature_c + winding_loss_w * p.thermal_resistance_k_w
        self.temperature_c = t_inf + (self.temperature_c - t_inf) * decay

        error = np.zeros(n, dtype=np.uint8)
        error[powered & ((volts < p.min_voltage_v) | (volts > p.max_voltage_v))] |= \
            ERROR_INPUT_VOLTAGE
        error[self._overheated] |= ERROR_OVERHEATING
        error[drive & (np.abs(u) >= umax) & (np.abs(w) < 0.05) & (umax > 0)] |= ERROR_OVERLOAD
        losses = None
        if rec:
            losses = {
                'standby': np.where(powered, p.standby_current_a * volts, 0.0),
                'extra': extra_w,
                'copper': winding_loss_w,
                'coulomb': sum_coulomb / n_sub,
                'gear': sum_gear / n_sub,
                'viscous': sum_visc / n_sub,
                'kinetic': 0.5 * p.reflected_inertia_kgm2 * (w * w - w0 * w0) / dt_s,
                'load': sum_pmech / n_sub,
                'brake': sum_brake / n_sub * volts,
            }
        return ServoOutput(
            position_rad=q + deflection,
            velocity_rad_s=w.copy(),
            torque_nm=np.where(drive | (self.velocity_rad_s == 0.0), -tau_ext, 0.0),
            current_a=current_a,
            temperature_c=self.temperature_c.copy(),
            load_fraction=np.where(drive, u, 0.0),
            power_w=power_w,
            mechanical_power_w=sum_pmech / n_sub,
            winding_loss_w=winding_loss_w,
            reported_temperature_c=np.rint(self.temperature_c).astype(np.int64),
            reported_voltage_v=np.round(volts * 10.0) / 10.0,
            error=error,
            torque_enabled=drive.copy(),
            winding_current_a=sum_i / n_sub,
            losses=losses,
        )
