"""Online energetic descriptors over whole gait cycles (core, no ROS).

Inputs are the converted samples of ``hexapod_common.conversions``; outputs are
:class:`Descriptors`, one per window of ``cycles`` whole gait cycles, with the definitions of
DESIGN §4:

- ``power_in`` [W]: mean electrical input power, the trapezoidal integral of V*I over the
  window divided by its length. The current's sign follows ``current_sign``: ``ros`` (negative
  while discharging, so P_in = -V*I), ``positive_discharge`` (P_in = V*I), or ``auto`` (decided
  once from the first samples: the sign that makes the median power positive).
- ``power_out`` [W]: mean mechanical output power, the mean over the window's joint samples of
  ``sum_i max(tau_i * qdot_i, 0)``: positive joint work only, the definition of
  :mod:`hexapod_energy.dynamics` (servos do not regenerate), from the joint efforts when
  ``/joint_states`` carries them, else from ``power_out_model(gait, mass)`` when one is given
  (:func:`model_power_out`), else 0. Drivers that publish efforts but no velocities
  (position-only + load drivers): the joint power comes from the positions, streaming, per
  joint name (joints may be split over several messages): over each interval between two
  consecutive samples of that joint the work is the trapezoid ``0.5 (tau_(k-1) + tau_k)
  (q_k - q_(k-1))`` and the interval's power that work over the interval's length, stamped at
  the interval's midpoint (a position step beyond pi is taken as its 2 pi representative nearest
  0: wrapped continuous joints); P_out is the mean of ``sum_i max(P_i, 0)`` as above, the
  positive part taken per joint and interval. Each such window carries the warning
  :data:`POSITION_POWER_NOTE`. On simulated EduBot runs (hip torques, 100 Hz) this P_out is
  within 1.6 % of the one from the velocities (running +0.75 %, jogging +1.6 %, pace +1.0 %,
  walk -0.5 %). With neither velocities nor positions the efforts give no P_out (as without
  efforts). With ``power_out_source='auto'`` the efforts must also
  behave like joint torques (:func:`implausible_effort_power`): their P_out below P_in, and
  some negative joint work (a walking robot's joints absorb energy every cycle: lowering legs,
  braking swings; the net joint power is a small part of the positive one). Servos without
  torque sensing report something else as effort: the AX series' present load is the PWM
  duty, which carries the back-EMF and so always has the velocity's sign. On the simulated
  AntBot such efforts give net / positive joint power 1.000 and P_out 7.1 W at 0.15 m/s and
  21.7 W at 0.3 m/s, where the joints deliver 0.20 W and 0.83 W (true torques: net / positive
  -0.05 to 0.09 over 0.1-0.6 m/s and duty factors 0.5-0.7). Refused efforts give way to the
  model when there is one (else P_out is NaN), with a warning naming the figures.
- ``speed`` [m/s]: from motion capture when poses cover the window (horizontal displacement /
  window; a gap in the poses up to 0.5 s across a bound is bridged, a window the poses cover
  at least half of takes their span, both warned: :func:`_track_speed`; non-finite poses are
  left out, noted once), else (with a warning naming the fallback when poses came) the gait
  schedule's step_length / (beta T), else from odometry (``nav_msgs/Odometry`` positions,
  differenced the same way in the odometry frame), else a given constant ``speed_mps``;
  with none of these the speed is 0 on the gait-schedule path (as before) and NaN on the
  joint path (unknown: CoT and specific resistance NaN).
- ``power_loss = power_in - power_out``, ``efficiency = power_out / power_in``,
  ``cost_of_transport = power_loss / speed``, ``specific_cost_of_transport = power_loss /
  (mass * speed)``, ``specific_resistance = power_in / (mass * g * speed)``.

Windows are decided by stamps, not arrival order: a window closes only once a battery sample
past its end has arrived, so live streams and replayed bags give identical numbers.

Time going backwards (a looped bag restarting, a simulation clock reset under
``use_sim_time``): a stream whose stamp falls more than ``time_jump_s`` behind its own
previous stamp restarts the accumulation from the new time (every buffer, the cycle
boundaries and the joint cycle tracker; the decided current sign is kept), noted once per
jump in :attr:`DescriptorAccumulator.notes_`; the other streams' samples from before the jump
that arrive afterwards are dropped until their own stamps jump too. Each loop of a looped bag
gives the same windows. Stamps a few ms out of order are unaffected.

Bounded memory: no window is longer than ``max_window_s``; samples older than that before the
newest stamp are dropped (``quiet_s`` before the cycle source's first sample; the last battery
sample before the cut is kept for interpolation),
and a pending window that would be longer is given up (the cycle source paused: counted in
``dropped_windows_``). While the cycle source (``/gait/phase``; on the joint path
``/joint_states``) has been quiet for ``quiet_s`` of battery stamps, a note says so, once per
pause; so does ``/battery_state`` quiet for ``quiet_s`` while the cycle source goes on (a power
monitor stopped: no window can complete). A window across a gap in ``/battery_state`` (an
interval over 5 times the stream's usual one) is flagged (``BATTERY_GAP_NOTE``), also one with
no sample at all inside the gap; the offline reader and ``energy_monitor`` leave such windows
out.

Cycle boundaries (``cycle_source``): ``gait_phase`` takes them from the wraps of the
``/gait/phase`` cycle phase; ``joints`` from the joint positions alone
(:class:`hexapod_energy.cycles.JointCycleTracker`), for robots whose gait code publishes no
``/gait/phase``; ``auto`` feeds the joint tracker until the first ``/gait/phase`` sample arrives
and from then on uses the gait schedule only (joint-derived boundaries not yet consumed are
dropped). On the joint path, without joint efforts P_out is NaN (the Eq. 6 model needs the
gait schedule), with a warning.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hexapod_common.clocks import FOREIGN_CLOCK_S, StreamClock, foreign_clock_note
from hexapod_common.conversions import (
    BatterySample,
    GaitPhaseSample,
    LEG_JOINT_RE,
    JointStateSample,
    LegJointFilter,
    OdometrySample,
    PoseSample,
    current_sign_factor,
)
from hexapod_common.series import robust_sigma, span_mean
from hexapod_energy import metrics
from hexapod_energy.cycles import CycleSettings, JointCycleTracker, unwrap_near
from hexapod_energy.metrics import G_MPS2

__all__ = [
    'MODEL_LEG_JOINTS',
    'model_leg_mismatch',
    'ArrivalClockGate',
    'AUTO_UNANIMOUS_SAMPLES',
    'CYCLE_QUIET_S',
    'MAX_WINDOW_S',
    'TIME_JUMP_S',
    'MIN_BATTERY_SAMPLES_PER_WINDOW',
    'SLOW_BATTERY_NOTE',
    'STILL_JOINTS_NOTE',
    'STILL_JOINTS_RAD',
    'G_MPS2',
    'EFFORT_MAX_NET_FRACTION',
    'POSITION_POWER_NOTE',
    'POSITION_DEGREES_NOTE',
    'VELOCITY_CONVERTED_NOTE',
    'VELOCITY_UNITS',
    'VELOCITY_UNITS_NOTE',
    'JointUnits',
    'VelocityScale',
    'joint_units',
    'velocity_scale',
    'velocityless_note',
    'CLOCK_MODEL_NOTE',
    'JOINT_WAIT_S',
    'is_clock_schedule',
    'is_stand_schedule',
    'DescriptorAccumulator',
    'Descriptors',
    'descriptors_from_powers',
    'gait_from_sample',
    'model_power_out',
    'implausible_effort_power',
    'joint_power_out_w',
    'resolve_current_sign',
]


#: least battery samples inside a window for its P_in to be trusted without a warning
MIN_BATTERY_SAMPLES_PER_WINDOW = 4
#: warning of a window whose P_in rests on fewer battery samples than that
SLOW_BATTERY_NOTE = (f'battery sampled slower than the gait: some windows hold fewer than '
                     f'{MIN_BATTERY_SAMPLES_PER_WINDOW} /battery_state samples, so their P_in is '
                     'interpolated between samples taken at a few gait phases (aliasing with the '
                     'gait possible; a monitor that averages its current is fine)')
#: warning of a window whose joint power came from position differences (no velocities)
POSITION_POWER_NOTE = ('no joint velocities: joint power from position differences '
                       '(trapezoid effort x position step per joint and sample interval)')



def velocityless_note(count: int) -> str:
    """Note for JointState messages without velocities whose joints have them elsewhere."""
    return (f'{count} /joint_states message(s) without velocities, for joints whose other '
            'messages carry them: left out of P_out (not mixed with position differences)')


#: the fastest speed [m/s] taken from a legged robot's gait schedule (as ``energy
#: --robot-speed`` and ``slip`` bound theirs): beyond it the schedule's units are wrong
MAX_SPEED_MPS = 20.0
#: the start of a window's warning for a schedule faster than MAX_SPEED_MPS
SCHEDULE_SPEED_NOTE = 'the gait schedule\'s speed is beyond any legged robot'


def schedule_speed_note(gait: Any) -> str:
    """The warning of a ``/gait/phase`` whose speed is above :data:`MAX_SPEED_MPS` (outside
    review, A5: step_length in mm read 160 m/s, CoT/M 0.0557 for 55.65)."""
    length = float(gait.step_length_m)
    return (f'{SCHEDULE_SPEED_NOTE}: {gait.speed_mps:.4g} m/s (step_length {length:g} / '
            f'(duty_factor {gait.duty_factor:g} x period {gait.period_s:g} s)), above '
            f'{MAX_SPEED_MPS:g} m/s: step_length looks like millimetres (GaitPhase '
            f'step_length and step_height are metres: {length:g} mm is {length / 1000:g} m); '
            'speed, cost of transport and specific resistance unknown')


#: joint velocity against the position's derivative (:func:`velocity_scale`): samples moving
#: slower than VELOCITY_CHECK_MIN_RAD_S by their positions, or over intervals longer than
#: VELOCITY_CHECK_MAX_DT_S, are not compared; a joint counts with VELOCITY_CHECK_MIN_JOINT_SAMPLES
#: moving samples, the estimate with VELOCITY_CHECK_MIN_SAMPLES over its joints; the last
#: VELOCITY_CHECK_KEEP samples of each joint are kept
VELOCITY_CHECK_MIN_RAD_S = 0.05
VELOCITY_CHECK_MAX_DT_S = 0.2
VELOCITY_CHECK_MIN_SAMPLES = 50
VELOCITY_CHECK_MIN_JOINT_SAMPLES = 10
VELOCITY_CHECK_KEEP = 400
#: the velocity units recognised (:func:`joint_units`): name and the factor of a velocity in
#: that unit over the same velocity in rad/s
VELOCITY_UNITS: tuple[tuple[str, float], ...] = (
    ('rad/s', 1.0), ('deg/s', 180.0 / math.pi), ('rpm', 30.0 / math.pi),
    ('rev/s', 0.5 / math.pi))
#: a measured factor within this ratio (either way) of a unit's is that unit: the units are at
#: least 6x apart; the simulated robot's rad/s velocities are 0.92-0.95 of the positions'
#: derivative (0.85 for one joint), its deg/s ones 53-56 times it
VELOCITY_UNIT_TOLERANCE = 1.25
#: the velocities say nothing of their unit when the joints' fits leave a median relative
#: residual above this (velocities unrelated to the positions: a driver filling one of them
#: from the commands), or when the pooled factor is not positive
VELOCITY_CHECK_MAX_RESIDUAL = 0.5
#: a joint whose factor is further than this ratio from the pooled one: the joints' velocities
#: are not in one unit (P_out from effort x velocity refused)
VELOCITY_JOINT_SPREAD = 2.0
#: the start of the warning of joint velocities in no recognised unit (P_out from effort x
#: velocity refused)
VELOCITY_UNITS_NOTE = 'the joint velocities are not rad/s'
#: the start of the note of joint velocities in a recognised unit, converted to rad/s
VELOCITY_CONVERTED_NOTE = 'joint velocities converted to rad/s'
#: the start of the note of joint positions in degrees
POSITION_DEGREES_NOTE = 'the joint positions are not radians'
#: a leg joint's swing between two turns of its motion (a turn: the position comes back by
#: more than POSITION_TURN) above this [rad]: more than a revolution and back, no leg joint's
#: in radians (a leg turning on, a Buehler clock's, makes no turns); the positions are
#: degrees when at least POSITION_DEG_MIN_SWINGS swings, and a quarter of all, are that large
#: (an encoder glitch is one or two)
POSITION_DEG_SWING = 2.5 * math.pi
POSITION_TURN = 0.2
POSITION_DEG_MIN_SWINGS = 12


@dataclass(frozen=True)
class VelocityScale:
    """JointState.velocity over the derivative of JointState.position (:func:`velocity_scale`).

    ``factor``: the pooled factor (the median of the joints'; NaN with too few moving
    samples, or no joint whose fit leaves a median relative residual of at most
    :data:`VELOCITY_CHECK_MAX_RESIDUAL`); ``joint_factors``: those joints' (a robust fit);
    ``residual``: the median over all the joints with enough samples of their fits' median
    relative residual; ``samples``: the moving samples compared."""

    factor: float = math.nan
    joint_factors: tuple[tuple[str, float], ...] = ()
    residual: float = math.nan
    samples: int = 0


def velocity_scale(pairs: Any) -> VelocityScale:
    """The factor between joint velocities and their positions' derivative: ``pairs`` maps each
    joint name to its moving samples (velocity, position derivative; an (n, 2) array or pairs).
    Per joint, the slope of the velocity against the derivative through the origin that
    minimises the absolute residuals (the median of the ratios weighted by the derivative's
    size: slow samples, whose derivative is mostly noise, count little, and outliers not at
    all); pooled, the median of the slopes of the joints they fit (a joint whose velocity
    does not follow its position, a passive one's, is left out)."""
    groups: dict[int, list[tuple[str, np.ndarray]]] = {}
    for name, rows in pairs.items():
        a = (rows if isinstance(rows, np.ndarray) else
             np.asarray(list(rows), dtype=float)).reshape(-1, 2)
        if a.shape[0] >= VELOCITY_CHECK_MIN_JOINT_SAMPLES:
            groups.setdefault(a.shape[0], []).append((str(name), a))
    factors: list[tuple[str, float, float]] = []
    n = 0
    for size, items in groups.items():   # joints with as many samples at once (all, usually)
        stack = np.stack([a for _, a in items])
        v, rate = stack[..., 0], stack[..., 1]
        ratio = v / rate
        order = np.argsort(ratio, axis=1, kind='stable')
        c = np.cumsum(np.take_along_axis(np.abs(rate), order, axis=1), axis=1)
        pick = np.argmax(c >= 0.5 * c[:, -1:], axis=1)
        k = np.take_along_axis(ratio, order, axis=1)[np.arange(len(items)), pick]
        fit = k[:, None] * rate
        scale = np.median(np.abs(fit), axis=1)
        miss = np.median(np.abs(v - fit), axis=1)
        residual = np.where(scale > 0, miss / np.where(scale > 0, scale, 1.0), math.inf)
        factors.extend((name, float(kk), float(r))
                       for (name, _), kk, r in zip(items, k, residual))
        n += size * len(items)
    if not factors or n < VELOCITY_CHECK_MIN_SAMPLES:
        return VelocityScale(samples=n)
    fitted = sorted((name, k) for name, k, r in factors if r <= VELOCITY_CHECK_MAX_RESIDUAL)
    return VelocityScale(factor=float(np.median([k for _, k in fitted])) if fitted
                         else math.nan, joint_factors=tuple(fitted),
                         residual=float(np.median([r for *_, r in factors])), samples=n)


class _PairRing:
    """The last :data:`VELOCITY_CHECK_KEEP` (velocity, position derivative) pairs of a joint."""

    __slots__ = ('_a', '_n')

    def __init__(self) -> None:
        self._a = np.empty((VELOCITY_CHECK_KEEP, 2))
        self._n = 0

    def append(self, v: float, rate: float) -> None:
        self._a[self._n % VELOCITY_CHECK_KEEP] = (v, rate)
        self._n += 1

    def values(self) -> np.ndarray:
        return self._a[:min(self._n, VELOCITY_CHECK_KEEP)]


@dataclass(frozen=True)
class JointUnits:
    """The joint velocities' and positions' units as the samples say (:func:`joint_units`).

    ``velocity_factor``: a velocity in ``velocity_unit`` over the same in rad/s (1 when
    nothing was recognised); ``position_factor``: 180 / pi for positions in degrees, else 1;
    ``refused``: the velocities follow the positions by a factor that is no unit (a gear
    ratio?) or by several (joints in other units): effort x velocity is not the joint power;
    ``note``: what to say ('' nothing)."""

    velocity_unit: str = 'rad/s'
    velocity_factor: float = 1.0
    position_factor: float = 1.0
    refused: bool = False
    note: str = ''


def _unit_of(factor: float) -> tuple[str, float] | None:
    for name, nominal in VELOCITY_UNITS:
        if factor > 0 and abs(math.log(factor / nominal)) <= math.log(VELOCITY_UNIT_TOLERANCE):
            return name, nominal
    return None


def joint_units(scale: VelocityScale, *, degree_swings: int = 0,
                largest_swing: float = math.nan) -> JointUnits:
    """What ``scale`` (and the joints' swings: ``degree_swings`` at least
    :data:`POSITION_DEG_MIN_SWINGS` swings above :data:`POSITION_DEG_SWING`, the largest
    ``largest_swing``, say the positions are degrees) says of the joint units.

    With positions in radians, a factor near a unit of :data:`VELOCITY_UNITS` (within
    :data:`VELOCITY_UNIT_TOLERANCE`) is that unit, converted; near pi / 180, the positions
    are degrees and the velocities rad/s. With positions in degrees (by their swings), the
    velocities' unit is the factor times 180 / pi (deg/s velocities: 1). Another factor
    consistent over the joints is refused (a gear ratio is not silently applied); velocities
    that do not follow the positions say nothing."""
    swing_deg = degree_swings >= POSITION_DEG_MIN_SWINGS
    deg = 180.0 / math.pi
    pos_factor = deg if swing_deg else 1.0
    swing_txt = (f'the joints swing up to {largest_swing:.3g} units between turns, more than '
                 'a revolution and back, which no leg joint does in radians')
    k = scale.factor
    fits = math.isfinite(k) and k > 0 and scale.residual <= VELOCITY_CHECK_MAX_RESIDUAL
    per_joint = (f'a robust fit per joint, {len(scale.joint_factors)} joint(s) '
                 f'{min(f for _, f in scale.joint_factors):.3g}..'
                 f'{max(f for _, f in scale.joint_factors):.3g}, pooled over '
                 f'{scale.samples} moving samples') if scale.joint_factors else ''
    if not fits:
        if swing_deg:
            return JointUnits(position_factor=deg, note=(
                f'{POSITION_DEGREES_NOTE}: {swing_txt}: the positions look like degrees (the '
                'contract is rad, REP-103); P_out from position differences x pi / 180, the '
                'motion checks in radians'))
        return JointUnits()
    if any(abs(math.log(f / k)) > math.log(VELOCITY_JOINT_SPREAD) if f > 0 else True
           for _, f in scale.joint_factors):
        return JointUnits(velocity_unit='', refused=True, note=(
            f'{VELOCITY_UNITS_NOTE}: JointState.velocity over the derivative of the positions '
            f'differs between the joints ({per_joint}; ' + ', '.join(
                f'{n} {f:.3g}' for n, f in scale.joint_factors[:8]) +
            (', ...' if len(scale.joint_factors) > 8 else '') + "): the joints' velocities "
            'are not in one unit, so effort x velocity is not the joint power'))
    unit = _unit_of(k * pos_factor)
    if unit == ('rad/s', 1.0) and swing_deg or \
            not swing_deg and _unit_of(k * deg) == ('rad/s', 1.0):
        # positions in degrees, velocities in rad/s: P_out from effort x velocity stands
        return JointUnits(position_factor=deg, note=(
            f'{POSITION_DEGREES_NOTE}: the derivative of JointState.position is {1 / k:.3g} '
            f'times the velocity ({per_joint}; 57.3 = degrees against rad/s)' +
            (f'; {swing_txt}' if swing_deg else '') + ': the positions look like degrees '
            '(the contract is rad, REP-103); P_out from effort x velocity is kept, the joint '
            'cycles read the positions, the motion checks in radians'))
    pos_txt = f', which are degrees ({swing_txt})' if swing_deg else ''
    if unit is None:
        return JointUnits(velocity_unit='', position_factor=pos_factor, refused=True, note=(
            f'{VELOCITY_UNITS_NOTE}: JointState.velocity is {k:.3g} times the derivative of '
            f'the positions ({per_joint}){pos_txt}, a factor of no unit recognised (' +
            ', '.join(f'{n} {f:.3g}' for n, f in VELOCITY_UNITS) +
            f', within {100 * (VELOCITY_UNIT_TOLERANCE - 1):.0f} %): a gear ratio or a '
            'driver\'s scale? Not applied: effort x velocity is not taken as the joint power'))
    name, nominal = unit
    if nominal == 1.0:
        return JointUnits()
    return JointUnits(velocity_unit=name, velocity_factor=nominal, position_factor=pos_factor,
                      note=(
        f'{VELOCITY_CONVERTED_NOTE}: JointState.velocity is {k:.3g} times the derivative of '
        f'the positions ({per_joint}){pos_txt}: the velocities are {name} (x {nominal:.4g} '
        f'the rad/s; the contract is rad/s, REP-103), divided by {nominal:.4g}: P_out from '
        'effort x velocity in rad/s'))


#: said once when /mocap/body gives a pose with a non-finite position
NONFINITE_POSE_NOTE = ('mocap/body poses with a non-finite position (NaN: the bridge lost the '
                       'body?) are left out of the speed; windows they leave without poses '
                       'are warned')


#: the start of a window's warning that ``/gait/phase`` and ``/joint_states`` name other legs
LEG_MISMATCH_NOTE = 'legs of /gait/phase and /joint_states differ'


#: a window whose joint efforts are all exactly 0.0 (a driver without an effort interface fills
#: the field with zeros): no efforts, not P_out 0 W and efficiency 0 (outside review, A3)
ZERO_EFFORT_NOTE = ('JointState.effort is 0.0 on every joint (a driver without an effort '
                    'interface fills it with zeros): taken as no joint efforts')


#: ``power_out_source='auto'`` refuses efforts whose net joint power is at least this fraction
#: of their positive joint power (no negative work: a duty signal, not a torque).
EFFORT_MAX_NET_FRACTION = 0.9


@dataclass(frozen=True)
class Descriptors:
    """Energetic descriptors of one window (fields as EnergeticDescriptors.msg)."""

    t_end_s: float
    window_s: float
    mass_kg: float
    speed_mps: float
    power_in_w: float
    power_out_w: float
    power_loss_w: float
    efficiency: float
    cost_of_transport_j_per_m: float
    specific_cost_of_transport: float
    specific_resistance: float
    cycles: int = 1
    warnings: tuple[str, ...] = ()
    speed_source: str = ''   # mocap, odometry, gait_schedule, given, none
    cycle_source: str = ''   # gait_phase or joints
    #: mean net (signed) joint power from the efforts [W]; NaN without efforts
    joint_power_net_w: float = math.nan
    #: where P_out came from: effort, model, none (unknown) or '' (0 W, no source)
    power_out_source: str = ''


def descriptors_from_powers(*, power_in_w: float, power_out_w: float, speed_mps: float,
                            mass_kg: float, window_s: float = 0.0, t_end_s: float = 0.0,
                            cycles: int = 1, warnings: tuple[str, ...] = (),
                            speed_source: str = '', cycle_source: str = '',
                            joint_power_net_w: float = math.nan,
                            power_out_source: str = '') -> Descriptors:
    """All descriptors from mean powers, speed and mass (NaN where undefined, e.g. v = 0)."""
    # the definitions are hexapod_energy.metrics' (DESIGN section 4), NaN where undefined
    loss = float(metrics.power_loss(power_in_w, power_out_w))
    eff = float(metrics.efficiency(power_in_w, power_out_w)) if power_in_w > 0 else math.nan
    # a negative input power (a current sign forced wrong) gives no costs either: CoT -271.9
    # and SR -7.17 were published beside a null efficiency (outside review C2)
    moving = speed_mps > 0 and mass_kg > 0 and not power_in_w <= 0
    return Descriptors(
        t_end_s=t_end_s, window_s=window_s, mass_kg=mass_kg, speed_mps=speed_mps,
        power_in_w=power_in_w, power_out_w=power_out_w, power_loss_w=loss, efficiency=eff,
        cost_of_transport_j_per_m=float(metrics.cost_of_transport(
            power_in_w, power_out_w, speed_mps)) if speed_mps > 0 and not power_in_w <= 0
        else math.nan,
        specific_cost_of_transport=float(metrics.specific_cost_of_transport(
            power_in_w, power_out_w, mass_kg, speed_mps)) if moving else math.nan,
        specific_resistance=float(metrics.specific_resistance(
            power_in_w, mass_kg, speed_mps)) if moving else math.nan,
        cycles=cycles, warnings=warnings, speed_source=speed_source,
        cycle_source=cycle_source, joint_power_net_w=joint_power_net_w,
        power_out_source=power_out_source)


def gait_from_sample(sample: GaitPhaseSample) -> Any:
    """``hexapod_gait.gait.GaitPattern`` of a converted ``/gait/phase`` sample."""
    from hexapod_gait.gait import GAIT_NAMES, GaitPattern

    name = sample.gait if sample.gait in GAIT_NAMES else 'custom'
    return GaitPattern(
        name=name, leg_names=tuple(sample.leg_names),
        phase_offsets=tuple(float(x) % 1.0 for x in sample.phase_offsets),
        duty_factor=sample.duty_factor, period_s=sample.period_s,
        step_length_m=sample.step_length_m, step_height_m=sample.step_height_m)


def model_power_out(output_power: Any, *, robot_mass_kg: float
                    ) -> Callable[[GaitPhaseSample, float], float]:
    """``f(gait_sample, mass_kg) -> P_out [W]`` from an
    :class:`hexapod_energy.prediction.OutputPowerModel` (Eq. 6, positive joint power), for
    :class:`DescriptorAccumulator` when ``/joint_states`` has no efforts.

    The payload is ``mass_kg - robot_mass_kg``; a standing or clock-driven schedule (period 0)
    gives 0 W; results are cached per schedule.
    """
    cache: dict[tuple[Any, ...], float] = {}

    def power_out_w(gait: GaitPhaseSample, mass_kg: float) -> float:
        key = (gait.gait, tuple(gait.leg_names), tuple(np.round(gait.phase_offsets, 12)),
               gait.duty_factor, gait.period_s, gait.step_length_m, gait.step_height_m,
               mass_kg)
        if key not in cache:
            if is_stand_schedule(gait) or not gait.leg_names:
                cache[key] = 0.0
            else:
                cache[key] = float(output_power.power_out_w(
                    gait_from_sample(gait), payload_kg=max(mass_kg - robot_mass_kg, 0.0)))
        return cache[key]

    return power_out_w


#: backward time jumps kept in ``time_jumps_`` (and noted): the latest ones
MAX_TIME_JUMPS_KEPT = 100

#: longest a complete window waits [s of battery time past its end] for joint states
#: stamped inside it that have not arrived yet (:meth:`DescriptorAccumulator._joints_pending`)
JOINT_WAIT_S = 1.0

#: a Buehler-clock schedule has no Eq. 6 P_out model: the window's P_out is unknown
CLOCK_MODEL_NOTE = ('a Buehler clock (rotating legs, no step length) and no usable joint '
                    'efforts: the Eq. 6 P_out model is for stepping servo legs; P_out unknown '
                    '(NaN)')


def is_clock_schedule(sample: Any) -> bool:
    """Whether a /gait/phase sample is a clock-driven schedule of rotating legs (the Buehler
    clock of RHex-class robots: gait ``buehler``, or a walking period with no step length),
    as ``hexapod-analyze energy`` reads a bag's."""
    return float(sample.period_s) > 0 and not is_stand_schedule(sample) and (
        sample.gait == 'buehler' or not float(sample.step_length_m) > 0)


def is_stand_schedule(sample: Any) -> bool:
    """Whether a /gait/phase sample is a stand of a stepping gait: period 0, or step length
    and height 0 and no clock sweep (``gait_scheduler``'s stand keeps its period: it was read
    live as a Buehler clock, P_out NaN with a note about rotating legs, where ``hexapod-analyze
    energy`` reads the same bag's stand as P_out 0 W)."""
    if not float(sample.period_s) > 0:
        return True
    return sample.gait != 'buehler' and not (
        float(sample.step_length_m) > 0 or float(sample.step_height_m) > 0 or
        float(getattr(sample, 'sweep_angle_rad', 0.0)) > 0)


def implausible_effort_power(effort_w: float, power_in_w: float, net_w: float) -> str:
    """Why a P_out from joint efforts cannot be the joints' output power ('' if it can).

    ``effort_w`` is the mean positive joint power from the efforts, ``net_w`` the mean signed
    one. The positive power must stay below the input power, and the joints must do some
    negative work: ``net_w < EFFORT_MAX_NET_FRACTION * effort_w``.
    """
    if not (math.isfinite(effort_w) and effort_w > 0.0):
        return ''
    if math.isfinite(power_in_w) and 0 < power_in_w <= effort_w:
        return (f'P_out from joint efforts ({effort_w:.3f} W) is not below P_in '
                f'({power_in_w:.3f} W): the efforts are not joint torques (a load or PWM '
                'reading, as AX-series servos report, or an X-series current not scaled to '
                'torque)')
    if math.isfinite(net_w) and net_w >= EFFORT_MAX_NET_FRACTION * effort_w:
        return (f'the joint efforts never do negative work (net / positive joint power '
                f'{net_w / effort_w:.3f}, P_out {effort_w:.3f} W): a drive duty that follows '
                'the velocity (a load or PWM reading, as AX-series servos report), not a '
                'torque')
    return ''


#: an isolated battery sample this many robust sigmas (and the run's median |power|) away
#: from its neighbours' median is a sensor glitch (offline readers leave it out)
GLITCH_SIGMAS = 20.0
#: ... when at most this many such samples come in a row (a real stall lasts longer)
GLITCH_MAX_RUN = 2
#: ... and such samples are at most this share of the series: more are the load's own
#: spikes (a touchdown current sampled slowly), kept
GLITCH_MAX_SHARE = 0.005


def battery_glitches(power_w: Any) -> np.ndarray:
    """Mask of isolated glitches in a battery power series (time order): samples further
    than :data:`GLITCH_SIGMAS` robust sigmas of the series' deviations from its running
    7-sample median, and than its median absolute power, from that median, in runs of at
    most :data:`GLITCH_MAX_RUN` samples, unless they are more than :data:`GLITCH_MAX_SHARE` of
    the series (the load's own spikes, kept). Three single-sample 100 A readings in a 15 s AntBot
    bag (1,500 samples) raised its P_in by 7 % (35.0 -> 37.5 W) without a word."""
    from scipy.ndimage import median_filter

    p = np.asarray(power_w, dtype=float)
    out = np.zeros(p.size, dtype=bool)
    if p.size < 8 or not np.all(np.isfinite(p)):
        return out
    dev = p - median_filter(p, size=7, mode='nearest')
    sigma = robust_sigma(dev, 0.0)
    far = np.abs(dev) > max(GLITCH_SIGMAS * sigma, float(np.median(np.abs(p))), 1e-9)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], far.astype(np.int8), [0]))))
    for a, b in zip(edges[::2], edges[1::2]):
        if b - a <= GLITCH_MAX_RUN:
            out[a:b] = True
    if out.sum() > GLITCH_MAX_SHARE * p.size:
        # so many short spikes are the load's own (an EduBot's touchdown current, one 10 ms
        # sample every 0.18 s at 100 Hz: 81 of 600 samples were left out, its P_in read
        # 35.0 W for 40.5 W), not a sensor's rare glitches
        out[:] = False
    return out


def _gap_in_window(t: np.ndarray, t0: float, t1: float, steps: Any, *,
                   stopped: bool = False) -> bool:
    """Whether the sorted stamps ``t`` leave a gap in the window ``[t0, t1]``: an interval
    between the last stamp before it (else ``t0``), those inside and the first after it over
    :data:`BATTERY_GAP_INTERVALS` times the stream's usual interval (the median of
    ``steps``) and 0.25 s, or no stamp in or after the window. The end is checked once a
    stamp after it has come, or up to ``t1`` when the stream is known to have ``stopped``
    (none came while the window waited for it)."""
    inside = t[(t >= t0) & (t < t1)]
    after = t[t >= t1][:1]
    if stopped and not after.size:
        after = np.array([t1])
    if not inside.size and not after.size:
        return True
    before = t[t < t0][-1:]
    pts = np.concatenate([before if before.size else [t0], inside, after])
    typical = float(np.median(steps)) if len(steps) else 0.0
    return pts.size > 1 and \
        bool(np.max(np.diff(pts)) > max(BATTERY_GAP_INTERVALS * typical, 0.25))


#: a motion-capture (or odometry) gap up to this long [s] across a window bound is bridged:
#: the body's position at the bound is interpolated between the poses around it (at most half
#: the window; always 0.1 of it). An occlusion across a cycle boundary every 5 s (0.16 s
#: between poses at 120 Hz) had sent 1 window in 5 to the gait schedule's speed in silence:
#: 0.200 m/s for the mocap's 0.250, specific resistance +25 % (an outside live review)
POSE_GAP_S = 0.5
#: a window whose bounds cannot be bridged takes its speed from the poses it holds when they
#: span at least this share of it (displacement over their span), said in its warnings
POSE_MIN_COVER = 0.5
#: the start of a window's warning that its speed is from motion capture over part of it
PARTIAL_POSE_NOTE = 'motion capture lost over part of the window'
#: the start of a window's warning that motion capture gave it no speed
POSE_FALLBACK_NOTE = 'no motion-capture speed for this window'


#: the speed sources as a window's warning names them
_SPEED_SOURCE_NAMES = {'gait_schedule': 'the gait schedule', 'odometry': '/odom',
                       'given': 'the given speed', 'none': 'nowhere: speed unknown'}


def _position_at(track: Sequence[tuple[float, ...]], t: float, n: int,
                 max_gap_s: float) -> tuple[np.ndarray, float] | None:
    """Position (first ``n`` coordinates) at ``t``, linearly interpolated between the two
    samples around it, and their distance apart [s]; None without a sample on each side
    within ``max_gap_s`` of each other."""
    before = [p for p in track if p[0] <= t]
    after = [p for p in track if p[0] >= t]
    if not before or not after:
        return None
    a, b = max(before), min(after)
    if b[0] - a[0] > max_gap_s:
        return None
    pa, pb = np.asarray(a[1:1 + n], dtype=float), np.asarray(b[1:1 + n], dtype=float)
    w = 0.0 if b[0] == a[0] else (t - a[0]) / (b[0] - a[0])
    return pa + w * (pb - pa), b[0] - a[0]


def _track_speed(track: Sequence[tuple[float, ...]], t0: float, t1: float,
                 n: int) -> tuple[float | None, str]:
    """Speed [m/s] over ``[t0, t1]`` from a pose track (first ``n`` coordinates), and a
    warning ('' when the poses cover the window).

    The speed over a window of whole gait cycles is the displacement between its bounds, each
    bound's position interpolated between the samples around it (the samples nearest inside
    cut a part of the cycle: an EduBot walk, whose body speed swings within the stride, read
    0.1802 m/s for 0.1813; an independent review). A gap around a bound up to
    :data:`POSE_GAP_S` (at most half the window; always 0.1 of it) is bridged, warned when it
    is over 0.1 of the window. A bound not bridged is replaced by the pose nearest it inside
    the window: the speed is the displacement over the poses' span, warned unless they reach
    within 0.1 of the window of both bounds; spanning less than :data:`POSE_MIN_COVER` of
    the window, None (the window has no speed from this track)."""
    w = t1 - t0
    inside = sorted(p for p in track if t0 <= p[0] <= t1)
    short = 0.1 * w
    ends: list[tuple[float, np.ndarray]] = []
    bridged = 0.0
    tracked_before = any(p[0] < t0 for p in track)
    for t, nearest in ((t0, inside[:1]), (t1, inside[-1:])):
        at = _position_at(track, t, n, max(short, min(POSE_GAP_S, 0.5 * w)))
        if at is not None:
            ends.append((t, at[0]))
            bridged = max(bridged, at[1])
        elif nearest and (t == t1 or tracked_before or nearest[0][0] - t0 < short):
            # the start bound falls back on the poses inside (beyond 0.1 of the window) only
            # after a loss of tracking (poses before it): a window the body enters the volume
            # in is not a whole window of motion (slip.json's whole cycles leave it out: SR
            # 1.743 against energy's 1.837 on a jogging run when it was taken)
            ends.append((nearest[0][0], np.asarray(nearest[0][1:1 + n], dtype=float)))
        else:
            return None, ''
    span = ends[1][0] - ends[0][0]
    if not span > 0 or span < POSE_MIN_COVER * w:
        return None, ''
    speed = float(math.hypot(*(ends[1][1] - ends[0][1]))) / span
    if ends[0][0] - t0 < short and t1 - ends[1][0] < short:
        if bridged <= short:
            return speed, ''
        return speed, (f'{PARTIAL_POSE_NOTE}: no pose for {bridged:.3f} s across a window '
                       'bound; the body position there interpolated across the gap')
    return speed, (f'{PARTIAL_POSE_NOTE}: speed from the poses over {100 * span / w:.0f} % '
                   f'of it ({ends[0][0] - t0:.3f} s after its start to {t1 - ends[1][0]:.3f} s '
                   'before its end)')


def joint_power_out_w(effort_nm: np.ndarray, velocity_rad_s: np.ndarray) -> float:
    """Instantaneous output power of one joint sample, ``sum_i max(tau_i qdot_i, 0)`` [W]."""
    return float(np.sum(np.clip(np.asarray(effort_nm) * np.asarray(velocity_rad_s), 0.0, None)))


def resolve_current_sign(voltage_v: np.ndarray, current_a: np.ndarray, mode: str) -> float:
    """Factor s such that P_in = s * V * I: -1 for ROS convention, +1 for positive discharge.

    ``auto`` picks the sign that makes the median input power positive
    (:func:`hexapod_common.conversions.current_sign_factor`).
    """
    return current_sign_factor(voltage_v, current_a, mode)


def _mean_joint_power_w(joint: list[tuple[float, tuple[str, ...], np.ndarray, bool, bool]], *,
                        signed: bool = False) -> float:
    """Sum over joint names of each joint's mean positive (or, ``signed``, net) power [W] (the
    mean of the per-sample sum when every sample has the same names), each mean over time
    (:func:`_time_mean`); ``joint`` holds each sample's stamp and signed ``effort *
    velocity``."""
    def part(power: np.ndarray) -> np.ndarray:
        return power if signed else np.clip(power, 0.0, None)

    names = joint[0][1]
    if all(j[1] == names for j in joint):
        t = np.array([j[0] for j in joint], dtype=float)
        return _time_mean(t, np.array([float(np.sum(part(j[2]))) for j in joint]))
    series: dict[str, tuple[list[float], list[float]]] = {}
    for t_s, js_names, power, *_ in joint:
        for name, p in zip(js_names, part(power)):
            ts, ps = series.setdefault(name, ([], []))
            ts.append(float(t_s))
            ps.append(float(p))
    return float(sum(_time_mean(np.array(ts), np.array(ps)) for ts, ps in series.values()))


def _time_mean(t_s: np.ndarray, values: np.ndarray) -> float:
    """Mean of ``values`` sampled at ``t_s``, each weighted by the time it stands for (half
    the spans to its neighbours; an end sample its one span): the samples' plain mean when
    they are evenly spaced, the time average when not. P_in is a time average too; a plain
    mean read a joint sampled twice as densely over half of each cycle +21 % (an outside
    review of the equations)."""
    if values.size < 3:
        return float(np.mean(values))
    order = np.argsort(t_s, kind='stable')
    t, v = t_s[order], values[order]
    w = np.empty_like(t)
    w[1:-1] = 0.5 * (t[2:] - t[:-2])
    w[0], w[-1] = t[1] - t[0], t[-1] - t[-2]
    total = float(np.sum(w))
    if not (total > 0 and np.all(np.isfinite(w))):
        return float(np.mean(values))
    return float(np.sum(w * v) / total)


#: joint states remembered to recognise a message delivered twice (stamp, names, values)
DUPLICATE_MEMORY = 64
#: odometry whose pose moves slower than this [m/s] over a window while its twist says faster
#: is a velocity-only estimator (pose left at 0): the twist's mean speed is used
ODOM_STILL_MPS = 1e-3
#: ``auto`` current sign: samples that decide it at once when their V * I all share a sign.
AUTO_UNANIMOUS_SAMPLES = 3
#: ... and each draws at least this much [W]: a sensor's idle offset (20 mA at 12 V before the
#: servos are powered) must not decide the sign of a whole run
AUTO_UNANIMOUS_MIN_W = 1.0
#: with current_sign auto, this many windows in a row of negative mean input power decide the
#: sign again (live; offline the whole run's median decides)
AUTO_RECHECK_WINDOWS = 3
#: a window whose battery samples leave a gap longer than this many median battery intervals
#: (and longer than 0.25 s) interpolates P_in across a recording gap: flagged
BATTERY_GAP_INTERVALS = 5.0
#: warning carried by such a window (offline readers leave these windows out)
BATTERY_GAP_NOTE = 'battery samples missing over part of the window (a recording gap)'
#: warning of a window whose P_out would come from joint efforts with samples missing over
#: part of it (a /joint_states gap; left out offline and not published live)
JOINT_GAP_NOTE = ('joint states missing over part of the window (a recording gap): P_out '
                  'from the efforts would miss it')
#: a stream's stamp this far [s] behind its previous one is a backward time jump (a looped
#: bag, a reset simulation clock); stamps less out of order than this are ordinary jitter
TIME_JUMP_S = 1.0
#: a walking schedule's window whose leg joints each moved less than this [rad] (their
#: position range; an AX-18A reads 0.005 rad a count) is a robot that did not follow it
STILL_JOINTS_RAD = 0.02
#: ... and whose joint velocities all stay below this [rad/s] (a driver that fills no positions
#: but velocities is moving)
STILL_JOINTS_RAD_S = 0.2
#: ... judged on joints whose position samples fall in at least this many of
#: :data:`STILL_PHASE_BINS` phase bins of the gait cycle (samples at one phase cannot show a
#: still joint: one per cycle reads a range of 0 on a walking robot)
STILL_MIN_PHASES = 3
STILL_PHASE_BINS = 10
#: warning of such a window (its speed and model P_out are not the schedule's)
STILL_JOINTS_NOTE = ('the leg joints did not move in this window while /gait/phase says '
                     'walking: the robot did not follow the schedule (joint_commands not '
                     'reaching the driver, the driver not started, torque off?)')
#: longest window [s]: older samples are dropped (the buffers' bound)
MAX_WINDOW_S = 60.0
#: an /odom speed this far (fraction) from the gait schedule's is reported (the schedule's is
#: used: mocap, else the schedule, else odometry)
ODOM_DISAGREE = 0.05
#: battery stamps [s] without a cycle-source sample before that is noted
CYCLE_QUIET_S = 5.0


def _legs_without_joints(legs: Sequence[str], joint_names: Sequence[str]) -> list[str]:
    """Legs of a gait schedule that no joint name belongs to (``<leg>_<joint>``); empty
    when no joint name starts with any of the schedule's legs (another naming convention:
    nothing to compare)."""
    have = {str(n).split('_', 1)[0] for n in joint_names if '_' in str(n)}
    if not have.intersection(legs):
        return []
    return [leg for leg in legs if leg not in have]


def _joint_legs_outside(legs: Sequence[str], joint_names: Sequence[str]) -> list[str]:
    """Legs with joints (``<leg>_<joint>``, contract leg names) that the gait schedule does
    not name: a gait node walking fewer legs than the robot has (their joints stand); empty
    when no joint name belongs to the schedule's legs (another naming convention)."""
    have = {str(n).split('_', 1)[0] for n in joint_names if '_' in str(n)}
    if not have.intersection(legs):
        return []
    return sorted(have - set(legs))


class ArrivalClockGate:
    """A live node's check, from each topic's first message on, for a topic stamped on another
    clock than the others (a micro-ROS battery board stamping its uptime, without time
    synchronisation): each message's header stamp minus its arrival on the node clock, per
    topic (its last message's); topics whose offsets lie within ``threshold_s`` of each other
    share a clock, the largest such group is the reference (on a tie, the one nearest the node
    clock; no judgement while the node clock reads 0, under ``use_sim_time`` before
    ``/clock``). A topic outside it is on another clock: :meth:`observe` says so once, and
    its messages are refused until their stamps come back to the reference (a board
    restarted and synchronised again), which is said too.

    The judgement at the 200th and 2000th message of all topics
    (:class:`hexapod_common.clocks.LiveClockWatch`) missed a board that joined after them,
    which read as a battery silent for 1795857615.9 s (logged 3 times a second, no window);
    a board restarted mid-run read as a looped bag, then as a stopped gait node (an outside
    live review). The threshold is the accumulator's far-clock bound (an hour): a looped bag
    or a replay moves every topic together, and a simulation clock resets the node clock too.
    """

    def __init__(self, threshold_s: float = FOREIGN_CLOCK_S) -> None:
        self.threshold_s = float(threshold_s)
        #: per topic: header stamp - arrival on the node clock of its last message [s]
        self.offsets: dict[str, float] = {}
        #: topics found on another clock, refused now; and every topic ever found so
        self.foreign: set[str] = set()
        self.reported: set[str] = set()
        #: messages refused as stamped on another clock
        self.refused = 0
        self._groups = 0

    def _reference(self, now_s: float) -> set[str] | None:
        """The topics on the reference clock (None: no judgement)."""
        order = sorted(self.offsets, key=self.offsets.__getitem__)
        groups: list[list[str]] = []
        for topic in order:
            if groups and self.offsets[topic] - self.offsets[groups[-1][-1]] <= \
                    self.threshold_s:
                groups[-1].append(topic)
            else:
                groups.append([topic])
        self._groups = len(groups)
        if len(groups) < 2:
            return None
        size = max(len(g) for g in groups)
        best = [g for g in groups if len(g) == size]
        if len(best) > 1:
            if now_s <= 0:
                return None
            best.sort(key=lambda g: min(abs(self.offsets[t]) for t in g))
        return set(best[0])

    def observe(self, topic: str, stamp_s: float, now_s: float) -> tuple[bool, str, str]:
        """One message: (keep it, log level '' / 'error' / 'info', text to log)."""
        if stamp_s == 0.0:
            return True, '', ''
        self.offsets[topic] = stamp_s - now_s
        ref = self._reference(now_s)
        far = ref is not None and topic not in ref
        if far:
            self.refused += 1
            if topic in self.foreign:
                return False, '', ''
            self.foreign.add(topic)
            self.reported.add(topic)
            assert ref is not None
            others = sorted(ref)
            ref_off = float(np.median([self.offsets[t] for t in others]))
            return False, 'error', (
                f'{topic} stamped on another clock: header stamps '
                f'{self.offsets[topic] - ref_off:+.1f} s from those of {", ".join(others)} '
                f'(each against the node clock on arrival; a board stamping its uptime, without '
                'time synchronisation?): its messages cannot be matched with the others\' and '
                'are left out until its stamps are on their clock; give the publisher a '
                'synchronised clock (offline, hexapod-analyze re-stamps it from the bag\'s '
                'receive times)')
        if topic in self.foreign:
            if ref is None and self._groups > 1:   # undecided (a tie): still refused
                self.refused += 1
                return False, '', ''
            self.foreign.discard(topic)
            return True, 'info', (f'{topic} stamped on the other topics\' clock again: its '
                                  'messages are used again')
        return True, '', ''


#: the joints of the Eq. 6 model's leg (AntBot's or ``--leg``'s: a 3-DOF leg,
#: :mod:`hexapod_energy.leg_description`)
MODEL_LEG_JOINTS = ('coxa', 'femur', 'tibia')


def model_leg_mismatch(joint_names: Sequence[str]) -> str:
    """Why the Eq. 6 model's 3-DOF leg cannot be this robot's leg, from the contract leg
    joints a run records: '' when every leg named has three joints (``<leg>_coxa``,
    ``_femur``, ``_tibia``, or three of other names a ``--leg`` file may describe), or no
    joint follows the contract's ``L1..Lk/R1..Rk_<joint>``; else the legs and their joints
    (a 12-servo hexapod's coxa and femur, a 4-DOF leg's tarsus: the model's 0.31 W was
    reported as their P_out, efficiency and CoT/M with a note that said to give --leg,
    which describes 3-DOF legs only: an outside review)."""
    legs: dict[str, set[str]] = {}
    for n in joint_names:
        if LEG_JOINT_RE.match(str(n)):
            leg, joint = str(n).split('_', 1)
            legs.setdefault(leg, set()).add(joint)
    bad: dict[tuple[str, ...], list[str]] = {}
    for leg, joints in sorted(legs.items()):
        if len(joints) != len(MODEL_LEG_JOINTS):
            bad.setdefault(tuple(sorted(joints)), []).append(leg)
    return '; '.join(f'{", ".join(lg)}: {", ".join(j)}' for j, lg in bad.items())


@dataclass
class DescriptorAccumulator:
    """Collects samples and emits :class:`Descriptors` per window of whole gait cycles.

    Parameters
    ----------
    mass_kg
        Total mass [kg], payload included.
    cycles
        Gait cycles per window.
    current_sign
        ``ros``, ``positive_discharge`` or ``auto`` (see module docstring).
    auto_samples
        Battery samples used to decide the sign in ``auto`` mode (the median of V * I); the
        sign is decided sooner, after ``AUTO_UNANIMOUS_SAMPLES`` samples, when every V * I so
        far has the same sign (a 1 Hz battery monitor would otherwise hold back a short run's
        first 20 s, or the whole of a 12 s run).
    power_out_model
        Optional ``f(gait_sample, mass_kg) -> W`` (e.g. :func:`model_power_out`).
    power_out_source
        ``auto`` (joint efforts when the window has any, else the model, else 0), ``effort``
        (efforts only, 0 without) or ``model`` (the model only; for drivers whose effort is not
        a torque, such as the AX series' PWM load).
    cycle_source
        ``gait_phase``, ``joints`` or ``auto`` (see the module docstring).
    speed_mps
        Constant speed [m/s] used when neither motion capture, odometry nor a gait schedule
        gives one; 0 = unknown.
    cycle_settings
        Settings of the joint-derived cycles.
    limits
        Actuator limits (``hexapod_gait.feasibility.ActuatorLimits``, phase durations on the
        100 mm / 40 mm tip path of the leg they were measured on, ``measured_on``, scaled to
        each schedule's step on ``leg`` by :func:`hexapod_energy.prediction.geometry_limits`);
        None: AntBot's. Every new schedule
        on ``/gait/phase`` is checked against them and against phases with no leg on the ground
        (:func:`hexapod_energy.recommend.infeasible_schedule`, as ``hexapod-analyze energy``
        checks a bag's): an infeasible one is noted once (``notes_``), its windows are still
        computed.
    leg
        The robot's leg (:class:`hexapod_energy.leg_description.LegDescription`) for that
        scaling; None: AntBot's.
    """

    mass_kg: float
    cycles: int = 1
    current_sign: str = 'ros'
    auto_samples: int = 20
    power_out_model: Callable[[GaitPhaseSample, float], float] | None = None
    power_out_source: str = 'auto'
    cycle_source: str = 'gait_phase'
    speed_mps: float = 0.0
    cycle_settings: CycleSettings = field(default_factory=CycleSettings)
    time_jump_s: float = TIME_JUMP_S
    max_window_s: float = MAX_WINDOW_S
    quiet_s: float = CYCLE_QUIET_S
    limits: Any = None
    leg: Any = None
    sign_: float | None = field(default=None, init=False)
    #: schedules found infeasible: (time [s], reasons)
    infeasible_: list[tuple[float, list[str]]] = field(default_factory=list, init=False)
    _checked: set[tuple[Any, ...]] = field(default_factory=set, init=False)
    #: events worth a warning (time jumps, a quiet cycle source, given-up windows), in order
    notes_: list[str] = field(default_factory=list, init=False)
    #: backward time jumps seen: (stream, previous stamp, new stamp) [s]
    time_jumps_: list[tuple[str, float, float]] = field(default_factory=list, init=False)
    #: /mocap/body samples left out: the previous pose repeated exactly (tracking lost)
    repeated_poses_: int = field(default=0, init=False)
    #: /mocap/body samples left out: a position not finite (a bridge's NaN while tracking
    #: is lost)
    nonfinite_poses_: int = field(default=0, init=False)
    # whether /mocap/body gave a pose since the start (or the last time jump): a window it
    # gives no speed then falls back with a warning
    _mocap_seen: bool = field(default=False, init=False)
    #: pending windows given up because they would be longer than ``max_window_s``
    dropped_windows_: int = field(default=0, init=False)
    #: samples dropped because they were stamped before a time jump but arrived after it
    _clk: StreamClock = field(init=False)
    _n_jumps: int = field(default=0, init=False)
    _negative_run: int = field(default=0, init=False)
    # battery samples since the sign was decided with P_in >= 1 W, <= -1 W
    _sign_votes: list[int] = field(default_factory=lambda: [0, 0], init=False)
    _quiet_noted: bool = field(default=False, init=False)
    _battery_quiet_noted: bool = field(default=False, init=False)
    _battery_foreign_noted: bool = field(default=False, init=False)
    # the last /battery_state intervals [s], for the gap check (the buffer is trimmed)
    _battery_steps: deque[float] = field(default_factory=lambda: deque(maxlen=64), init=False)
    _joint_steps: deque[float] = field(default_factory=lambda: deque(maxlen=64), init=False)
    sign_note_: str = field(default='', init=False)
    _battery: list[tuple[float, float]] = field(default_factory=list, init=False)
    _pending_battery: list[BatterySample] = field(default_factory=list, init=False)
    # (stamp, joint names, per-joint signed power [W], from position differences) of each
    # JointState
    _joint: list[tuple[float, tuple[str, ...], np.ndarray, bool]] = field(
        default_factory=list, init=False)
    #: leg joint positions, for the still-robot check (:meth:`_joint_motion_rad`)
    # (stamp, names, positions, largest |velocity|)
    _leg_pos: list[tuple[float, tuple[str, ...], np.ndarray, float]] = field(
        default_factory=list, init=False)
    _poses: list[tuple[float, float, float, float]] = field(default_factory=list, init=False)
    _boundaries: list[float] = field(default_factory=list, init=False)
    _gait: GaitPhaseSample | None = field(default=None, init=False)
    # recent /gait/phase samples: a window takes the schedule in force at its end, though it
    # may be computed later (waiting for late joint states)
    _gait_hist: list[GaitPhaseSample] = field(default_factory=list, init=False)
    # per joint name, the stamp of its last joint-power sample (a window waits for them)
    _joint_last: dict[str, float] = field(default_factory=dict, init=False)
    _last_phase: tuple[float, float] | None = field(default=None, init=False)
    # the schedule the current run of windows is under (see _schedule_break)
    _ref_gait: GaitPhaseSample | None = field(default=None, init=False)
    # start [s] of the current standing stretch (None: standing since the first sample)
    _stand_anchor: float | None = field(default=None, init=False)
    #: schedule breaks: (time [s], reason) where no window may span
    schedule_breaks_: list[tuple[float, str]] = field(default_factory=list, init=False)
    #: windows whose /odom speed differs from the schedule's used one by more than
    #: ODOM_DISAGREE: (schedule speed, odometry speed) [m/s]
    odometry_disagreements_: list[tuple[float, float]] = field(default_factory=list,
                                                               init=False)
    _window_start: float | None = field(default=None, init=False)
    _odom: list[tuple[float, float, float, float]] = field(default_factory=list, init=False)
    _tracker: JointCycleTracker | None = field(default=None, init=False)
    _seen_gait: bool = field(default=False, init=False)
    #: joint samples that gave a joint power (from velocities or position differences)
    joint_power_samples_: int = field(default=0, init=False)
    #: of those, the samples whose efforts were all exactly 0.0 (:data:`ZERO_EFFORT_NOTE`)
    zero_effort_samples_: int = field(default=0, init=False)
    #: per joint name: (velocity, d(position)/dt) of its last VELOCITY_CHECK_KEEP moving
    #: samples (:meth:`joint_units_`)
    _velocity_pairs: dict[str, _PairRing] = field(default_factory=dict, init=False)
    #: per joint name: [last position, last turn, running extreme, direction] (the swings
    #: between turns, :data:`POSITION_DEG_SWING`)
    _swing: dict[str, list[float]] = field(default_factory=dict, init=False)
    #: swings between turns seen, those above POSITION_DEG_SWING, and the largest [position
    #: units]
    swings_: int = field(default=0, init=False)
    degree_swings_: int = field(default=0, init=False)
    largest_swing_: float = field(default=0.0, init=False)
    # the unit notes said once (notes_), live as offline
    _units_said: set[str] = field(default_factory=set, init=False)
    _velocity_prev: dict[tuple[str, ...], tuple[float, np.ndarray, np.ndarray]] = field(
        default_factory=dict, init=False)
    #: per joint name: samples whose effort * velocity was finite / not finite (left out)
    joint_power_count_: dict[str, int] = field(default_factory=dict, init=False)
    nonfinite_joint_power_: dict[str, int] = field(default_factory=dict, init=False)
    #: joints that are not a leg's, left out once a leg joint is named (``note()`` says which)
    leg_joints_: LegJointFilter = field(default_factory=LegJointFilter, init=False)
    #: joint states that repeated a recent one exactly (a message delivered twice): left out
    duplicate_joint_states_: int = field(default=0, init=False)
    _recent_js: dict[tuple[float, tuple[str, ...]], tuple[bytes, bytes, bytes]] = field(
        default_factory=dict, init=False)
    # per joint name: (stamp, position, effort) of its last sample (velocity-less drivers)
    _last_joint: dict[str, tuple[float, float, float]] = field(default_factory=dict,
                                                                init=False)
    #: joint names that came with velocities in some message: a message of theirs without
    #: velocities is left out of P_out (mixing position-difference power over a longer
    #: interval with effort x velocity read +2.3 % when 10 % of the messages lacked them)
    velocity_joints_: set[str] = field(default_factory=set, init=False)
    #: JointState messages left out of P_out for that (some of their joints)
    velocityless_skipped_: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        #: every joint name taken (legs only once a leg joint is named): the Eq. 6 model's
        #: 3-DOF leg against the robot's legs (model_leg_mismatch)
        self._joint_names_seen: set[str] = set()
        self._clk = StreamClock(self.time_jump_s, self._restart,
                                lambda stream, t: self.notes_.append(
                                    foreign_clock_note(stream, t)))
        if self.mass_kg <= 0:
            raise ValueError(f'mass_kg must be > 0, got {self.mass_kg}')
        if self.cycles < 1:
            raise ValueError(f'cycles must be >= 1, got {self.cycles}')
        if self.power_out_source not in ('auto', 'effort', 'model'):
            raise ValueError('power_out_source must be auto, effort or model, got '
                             f'{self.power_out_source!r}')
        if self.cycle_source not in ('auto', 'gait_phase', 'joints'):
            raise ValueError('cycle_source must be auto, gait_phase or joints, got '
                             f'{self.cycle_source!r}')
        if not (math.isfinite(self.speed_mps) and self.speed_mps >= 0):
            raise ValueError(f'speed_mps must be finite and >= 0, got {self.speed_mps}')
        if not (self.time_jump_s > 0 and self.max_window_s > 0 and self.quiet_s > 0):
            raise ValueError('time_jump_s, max_window_s and quiet_s must be > 0')
        if self.cycle_source != 'gait_phase':
            self._tracker = JointCycleTracker(self.cycle_settings)
        if self.current_sign != 'auto':
            self.sign_ = resolve_current_sign(np.zeros(1), np.zeros(1), self.current_sign)

    # -- time ------------------------------------------------------------------------------
    @property
    def stale_samples_(self) -> int:
        """Samples dropped as stamped before a time jump but arriving after it."""
        return self._clk.stale_samples

    def _restart(self, stream: str, last: float, t: float) -> None:
        """Time went back on ``stream`` from ``last`` to ``t``: start again from ``t``."""
        self.time_jumps_.append((stream, last, t))
        self._n_jumps += 1
        del self.time_jumps_[:-MAX_TIME_JUMPS_KEPT]   # bounded, however long it goes on
        if self._n_jumps <= MAX_TIME_JUMPS_KEPT:
            self.notes_.append(f'time jumped back {last - t:.3f} s on {stream} ({last:.3f} s '
                               f'-> {t:.3f} s: a looped bag or a reset simulation clock?): '
                               'accumulation restarted from the new time' +
                               ('; further jumps are not noted'
                                if self._n_jumps == MAX_TIME_JUMPS_KEPT else ''))
        self._restart_state()

    def _restart_state(self) -> None:
        """Drop everything accumulated: time went back."""
        # (the stream clock has started again from t and marked the other streams' stale)
        self._quiet_noted = False
        self._battery_quiet_noted = False
        self._battery_foreign_noted = False
        self._battery_steps.clear()
        self._joint_steps.clear()
        self._pending_battery = []
        self._battery = []
        self._joint = []
        self._leg_pos = []
        self._poses = []
        self._mocap_seen = False
        self._odom = []
        self._boundaries = []
        self._gait = None
        self._gait_hist = []
        self._joint_last = {}
        self._last_phase = None
        self._ref_gait = None
        self._window_start = None
        self._last_joint = {}
        self._seen_gait = False
        self._tracker = (JointCycleTracker(self.cycle_settings)
                         if self.cycle_source != 'gait_phase' else None)

    def _bound(self) -> None:
        """Drop what no window can still use: windows are at most ``max_window_s`` long."""
        if self._clk.newest is None:
            return
        # before the cycle source's first sample no boundary exists: a first window starts
        # after it, so a few seconds of data suffice
        horizon = self.max_window_s if any(k in self._clk.last for k in self._cycle_streams()) \
            else min(self.max_window_s, self.quiet_s)
        cut = self._clk.newest - horizon
        if self._window_start is not None and self._window_start < cut:
            self._window_start = None
            self.dropped_windows_ += 1
            if self.dropped_windows_ in (1, 10, 100) or self.dropped_windows_ % 1000 == 0:
                self.notes_.append(f'a window longer than {self.max_window_s:g} s given up '
                                   f'(the cycle source paused?) [{self.dropped_windows_} so '
                                   'far]')
        if self._boundaries and self._boundaries[0] < cut:
            self._boundaries = [b for b in self._boundaries if not b < cut]
        # amortised: trim once the oldest entry is half a horizon past the cut
        slack = cut - 0.5 * horizon
        # (the battery's first entry may be the one kept before the cut: look at its second)
        if any(len(buf) > k and buf[k][0] < slack
               for buf, k in ((self._battery, 1), (self._joint, 0), (self._poses, 0),
                              (self._odom, 0), (self._leg_pos, 0))) or \
                (len(self._gait_hist) > 1 and self._gait_hist[1].t_s < slack):
            self._trim(cut, keep_s=0.0)

    def _cycle_streams(self) -> tuple[str, ...]:
        """The streams the cycle boundaries come from now."""
        if self.joint_cycles_ or (self.cycle_source == 'auto' and not self._seen_gait):
            return ('joint_states',) if self.cycle_source == 'joints' else \
                ('gait/phase', 'joint_states')
        return ('gait/phase',)

    def _check_quiet(self, t: float) -> None:
        """Note (once per pause) a cycle source quiet for ``quiet_s`` while batteries come."""
        streams = self._cycle_streams()
        seen = [self._clk.last[k] for k in streams if k in self._clk.last]
        ref = max(seen) if seen else self._clk.first
        if ref is None or t - ref < self.quiet_s:
            if seen and t - max(seen) < self.quiet_s:
                self._quiet_noted = False
            return
        if not self._quiet_noted:
            self._quiet_noted = True
            what = ' or '.join(f'/{k}' for k in streams)
            self.notes_.append(
                f'no {what} for {t - ref:.1f} s while /battery_state arrives: no gait cycle '
                f'can complete a window (gait node stopped?); data older than '
                f'{self.max_window_s:g} s is dropped')

    def _check_battery_quiet(self, t: float) -> None:
        """Note (once per pause) ``/battery_state`` quiet for ``quiet_s`` while the cycle
        source goes on: no window can complete (before, the monitor fell silent without a
        word)."""
        last = self._clk.last.get('battery_state')
        ref = last if last is not None else self._clk.first
        if last is not None and t - ref > FOREIGN_CLOCK_S:
            if self._battery_foreign_noted:
                return
            self._battery_foreign_noted = self._battery_quiet_noted = True
            self.notes_.append(
                f'/battery_state stamped {t - ref:.0f} s behind the gait cycles: on another '
                'clock (a board stamping its uptime, without time synchronisation?); no window '
                'can complete until it is stamped on theirs')
            return
        if ref is None or t - ref < self.quiet_s or self._battery_quiet_noted:
            return
        self._battery_quiet_noted = True
        what = ('no /battery_state yet' if last is None else
                f'no /battery_state for {t - ref:.1f} s')
        self.notes_.append(
            f'{what} while the gait cycles go on: no window can complete (power monitor '
            'stopped, or its topic named otherwise?); windows across the gap will be left out')

    # -- inputs ----------------------------------------------------------------------------
    def add_battery(self, sample: BatterySample) -> list[Descriptors]:
        """Add one battery sample; returns the windows this sample completes."""
        prev = self._clk.last.get('battery_state')
        if not self._clk.observe('battery_state', sample.t_s):
            return []
        if prev is not None and sample.t_s > prev:
            self._battery_steps.append(sample.t_s - prev)
        cycle = [self._clk.last[k] for k in self._cycle_streams() if k in self._clk.last]
        if not cycle or sample.t_s >= max(cycle) - self.quiet_s:
            # the pause is over only when the battery is back on the gait cycles' time: a board
            # stamping its uptime (no time sync) reset it at every accepted sample, and 'no
            # /battery_state for 1795857615.9 s' was logged 3 times a second (an outside review)
            self._battery_quiet_noted = self._battery_foreign_noted = False
        self._check_quiet(sample.t_s)
        self._bound()
        if self.sign_ is None:
            self._pending_battery.append(sample)
            v = np.array([s.voltage_v for s in self._pending_battery])
            i = np.array([s.current_a for s in self._pending_battery])
            vi = v * i
            unanimous = (len(vi) >= AUTO_UNANIMOUS_SAMPLES and
                         bool(np.all(np.abs(vi) >= AUTO_UNANIMOUS_MIN_W)) and
                         (bool(np.all(vi > 0)) or bool(np.all(vi < 0))))
            if len(self._pending_battery) < self.auto_samples and not unanimous:
                return []
            self.sign_ = resolve_current_sign(v, i, 'auto')
            self.sign_note_ = ('current sign auto-detected: ' +
                               ('ROS convention (negative while discharging)'
                                if self.sign_ < 0 else 'positive while discharging'))
            pending, self._pending_battery = self._pending_battery, []
            out: list[Descriptors] = []
            for s in pending:
                out.extend(self._add_power(s))
            return out
        return self._add_power(sample)

    def _add_power(self, sample: BatterySample) -> list[Descriptors]:
        assert self.sign_ is not None
        p = self.sign_ * sample.voltage_v * sample.current_a
        if p >= AUTO_UNANIMOUS_MIN_W:
            self._sign_votes[0] += 1
        elif p <= -AUTO_UNANIMOUS_MIN_W:
            self._sign_votes[1] += 1
        self._battery.append((sample.t_s, p))
        return self._emit()

    @property
    def joint_cycles_(self) -> bool:
        """Whether the windows come from the joint-derived cycles (no /gait/phase used)."""
        return self._tracker is not None and not self._seen_gait

    @property
    def tracker_(self) -> JointCycleTracker | None:
        """The joint cycle tracker (None on the gait-schedule path)."""
        return self._tracker

    def add_joint_state(self, sample: JointStateSample) -> list[Descriptors]:
        """Add joint efforts with velocities (or, without velocities, with positions: power from
        position differences) and, on the joint path, positions; returns the windows the new
        cycle boundaries complete. Efforts with neither are ignored.

        Drivers that publish a robot's joints in several JointState messages (one per servo
        bus or leg) are handled: P_out is the sum over joint names of each joint's mean
        positive power over the window.
        """
        if not self._clk.observe('joint_states', sample.t_s):
            return []
        # joints that are not a leg's (a gripper beside the legs): out of cycles and P_out
        undecided = self.leg_joints_.legs_present is None
        legs = self.leg_joints_.apply(sample)
        if undecided and self.leg_joints_.legs_present:
            self._purge_non_leg_joints()
        if legs is None or self._duplicate_joint_state(legs):
            return []
        self._joint_names_seen.update(legs.names)
        return self._add_joint_sample(legs)

    def _purge_non_leg_joints(self) -> None:
        """The stream has just named a leg joint (live): what came before it named none (a
        gripper's driver started before the legs'), so its joint power and joint cycles are
        forgotten, as offline, where the whole bag decides, they are never taken."""
        is_leg = LegJointFilter.is_leg
        self._joint = [j for j in self._joint if any(is_leg(n) for n in j[1])]
        self._leg_pos = []
        for store in (self._last_joint, self._joint_last, self.joint_power_count_,
                      self.nonfinite_joint_power_):
            for name in [n for n in store if not is_leg(n)]:
                del store[name]
        self.velocity_joints_ = {n for n in self.velocity_joints_ if is_leg(n)}
        for units in (self._velocity_pairs, self._swing):
            for name in [n for n in units if not is_leg(n)]:
                del units[name]
        if self._tracker is not None:
            self._tracker = JointCycleTracker(self.cycle_settings)

    def _add_joint_sample(self, sample: JointStateSample) -> list[Descriptors]:
        """:meth:`add_joint_state` for one sample of leg joints, not a duplicate."""
        if self.joint_cycles_:
            self._check_battery_quiet(sample.t_s)
        if sample.position.size == len(sample.names) and sample.position.size:
            self._track_swings(sample)
            vel = np.abs(np.asarray(sample.velocity, dtype=float))
            vel = vel[np.isfinite(vel)]
            self._leg_pos.append((sample.t_s, tuple(sample.names),
                                  np.asarray(sample.position, dtype=float),
                                  float(vel.max()) if vel.size else 0.0))
        if sample.velocity.size == sample.position.size == len(sample.names) and \
                sample.velocity.size:
            self._compare_velocity(sample)
        if sample.effort.size and sample.velocity.size == sample.effort.size:
            power = np.asarray(sample.effort, dtype=float) * np.asarray(sample.velocity,
                                                                        dtype=float)
            ok = np.isfinite(power)
            names = tuple(sample.names)
            self.velocity_joints_.update(names)
            if not np.all(ok):
                # a joint without an effort interface (ros2_control reports NaN) or a glitch:
                # that joint is left out of this sample, the others still count
                for name in np.asarray(names, dtype=object)[~ok]:
                    self.nonfinite_joint_power_[name] = \
                        self.nonfinite_joint_power_.get(name, 0) + 1
                names = tuple(n for n, k in zip(names, ok) if k)
                power = power[ok]
            for name in names:
                self.joint_power_count_[name] = self.joint_power_count_.get(name, 0) + 1
                self._joint_last[name] = max(sample.t_s, self._joint_last.get(name, -math.inf))
            if names:
                effort = np.asarray(sample.effort, dtype=float)
                zero = bool(np.all(effort[np.isfinite(effort)] == 0.0))
                self._push_joint((sample.t_s, names, power, False, zero))
                self.joint_power_samples_ += 1
                self.zero_effort_samples_ += zero
        elif sample.effort.size and sample.position.size == sample.effort.size:
            self._add_position_power(sample)
        if not self.joint_cycles_:
            # a window waiting for this stream's late samples may be complete now
            return self._emit() if self._window_start is not None else []
        assert self._tracker is not None
        evaluations = self._tracker.evaluations_
        new = self._tracker.add(sample.t_s, sample.names, sample.position)
        if not new:
            if self._tracker.evaluations_ != evaluations and self._window_start is None and \
                    not self._boundaries and self._tracker.origin_s is not None:
                self._trim(self._tracker.origin_s)  # nothing pending: drop unneeded data
            return []
        self._boundaries.extend(new)
        return self._emit()

    def _compare_velocity(self, sample: JointStateSample) -> None:
        """Each moving joint's velocity (mean of this and its previous sample's) and its
        position's derivative between them, kept for :meth:`joint_units_` (deg/s velocities
        with rad positions read P_out 21.5 W for 0.375 W and passed every test: outside
        review, B1)."""
        names = tuple(sample.names)
        q = np.asarray(sample.position, dtype=float)
        v = np.asarray(sample.velocity, dtype=float)
        prev = self._velocity_prev.get(names)
        self._velocity_prev[names] = (sample.t_s, q, v)
        if len(self._velocity_prev) > 64:   # names that keep changing: forget the oldest
            del self._velocity_prev[next(iter(self._velocity_prev))]
        if prev is None:
            return
        dt = sample.t_s - prev[0]
        if not 0.0 < dt <= VELOCITY_CHECK_MAX_DT_S:
            return
        dq = q - prev[1]
        dq = dq - 2.0 * math.pi * np.round(dq / (2.0 * math.pi))
        rate = dq / dt
        mean_v = 0.5 * (v + prev[2])
        ok = np.isfinite(rate) & np.isfinite(mean_v) & \
            (np.abs(rate) > VELOCITY_CHECK_MIN_RAD_S) & (mean_v != 0.0)
        for k in np.flatnonzero(ok):
            pairs = self._velocity_pairs.get(names[k])
            if pairs is None:
                if len(self._velocity_pairs) >= 256:   # names that keep changing
                    continue
                pairs = self._velocity_pairs[names[k]] = _PairRing()
            pairs.append(float(mean_v[k]), float(rate[k]))

    def _track_swings(self, sample: JointStateSample) -> None:
        """Each joint's swings between turns of its motion (a turn: its position back by more
        than :data:`POSITION_TURN` from the extreme; steps unwrapped by whole turns of 2 pi,
        so a leg turning on in radians never turns), for the positions-in-degrees check of
        :func:`joint_units`."""
        for name, q in zip(sample.names, np.asarray(sample.position, dtype=float)):
            if not math.isfinite(q):
                continue
            st = self._swing.get(name)
            if st is None:
                if len(self._swing) < 256:
                    self._swing[name] = [float(q), float(q), float(q), 0.0]
                continue
            q = st[0] + (unwrap_near(float(q), st[0]) - st[0])   # the unwrapped track
            st[0] = q
            direction = st[3]
            if direction == 0.0:
                if abs(q - st[1]) > POSITION_TURN:
                    st[2], st[3] = q, math.copysign(1.0, q - st[1])
                    st[1] = math.nan   # the start: no turn yet
                continue
            if direction * (q - st[2]) >= 0.0:
                st[2] = q
            elif direction * (st[2] - q) > POSITION_TURN:   # a turn at the extreme
                if math.isfinite(st[1]):
                    swing = abs(st[2] - st[1])
                    self.swings_ += 1
                    self.degree_swings_ += swing > POSITION_DEG_SWING
                    self.largest_swing_ = max(self.largest_swing_, swing)
                st[1], st[2], st[3] = st[2], q, -direction

    def velocity_scale_(self) -> VelocityScale:
        """The joint velocities against their positions' derivative (:func:`velocity_scale`)
        over the kept moving samples."""
        return velocity_scale({name: ring.values() for name, ring in
                               self._velocity_pairs.items()})

    def velocity_ratio(self) -> float:
        """The pooled factor of :meth:`velocity_scale_` (NaN with fewer than
        :data:`VELOCITY_CHECK_MIN_SAMPLES` moving samples): 1 for consistent units."""
        return self.velocity_scale_().factor

    def joint_units_(self) -> JointUnits:
        """The joint units the samples so far say (:func:`joint_units`): the velocities'
        factor, and the joints' swings when a quarter of them are beyond a revolution."""
        swings = self.degree_swings_ if 4 * self.degree_swings_ >= self.swings_ else 0
        return joint_units(self.velocity_scale_(), degree_swings=swings,
                           largest_swing=self.largest_swing_)

    def _duplicate_joint_state(self, sample: JointStateSample) -> bool:
        """Whether ``sample`` repeats one of the last :data:`DUPLICATE_MEMORY` joint states
        exactly (stamp, names and values): the same message delivered twice (``bag_replay``
        publishes a bag's duplicated messages twice; a bridge or a recorder may too). Counted
        in ``duplicate_joint_states_`` and left out: each joint's mean power over a window is
        a mean over its samples, so a duplicate counted twice (an outside review: 10 % of
        the messages recorded twice moved live windows' P_out -7.6 to +5.6 %, where offline,
        which drops duplicates as it reads, matched)."""
        key = (sample.t_s, tuple(sample.names))
        values = (sample.position.tobytes(), sample.velocity.tobytes(),
                  sample.effort.tobytes())
        seen = self._recent_js.get(key)
        if seen == values:
            self.duplicate_joint_states_ += 1
            return True
        self._recent_js[key] = values
        if len(self._recent_js) > DUPLICATE_MEMORY:
            del self._recent_js[next(iter(self._recent_js))]
        return False

    def _push_joint(self, entry: tuple[float, tuple[str, ...], Any, bool, bool]) -> None:
        """One joint-power sample; its interval from the previous one is kept for the gap
        check (split messages of one frame, a fraction of a ms apart, are not intervals)."""
        if self._joint and entry[0] - self._joint[-1][0] > 1e-3:
            self._joint_steps.append(entry[0] - self._joint[-1][0])
        self._joint.append(entry)

    def _joint_gap(self, t0: float, t1: float) -> bool:
        """Whether the joint-power samples leave a gap in the window (:func:`_gap_in_window`):
        P_out from efforts would miss part of it."""
        if not self.joint_power_samples_:
            return False
        # the window waited for late joint states (_joints_pending) and none came past its
        # end: the stream stopped inside it (its P_out used to be the mean of the part before)
        return _gap_in_window(np.sort([j[0] for j in self._joint]), t0, t1,
                              self._joint_steps, stopped=True)

    def _add_position_power(self, sample: JointStateSample) -> None:
        """Joint power without velocities: per joint name, the trapezoid work
        ``0.5 (tau_(k-1) + tau_k) (q_k - q_(k-1))`` over the interval since that joint's
        previous sample, divided by its length, stamped at the interval's midpoint (the
        position step taken as the 2 pi representative nearest 0 when it exceeds pi)."""
        names: list[str] = []
        power: list[float] = []
        mids: list[float] = []
        taus: list[float] = []
        t = float(sample.t_s)
        skipped = False
        for name, q, tau in zip(sample.names, np.asarray(sample.position, dtype=float),
                                np.asarray(sample.effort, dtype=float)):
            if name in self.velocity_joints_:
                skipped = True   # its other messages carry velocities: not mixed with them
                continue
            if not (math.isfinite(q) and math.isfinite(tau)):
                continue
            prev = self._last_joint.get(name)
            if prev is not None and t <= prev[0]:
                continue  # a stale or repeated sample: keep the newer one
            self._last_joint[name] = (t, float(q), float(tau))
            if prev is None:
                continue
            t0, q0, tau0 = prev
            dq = unwrap_near(float(q), q0) - q0
            names.append(name)
            taus += [tau0, float(tau)]
            power.append(0.5 * (tau0 + float(tau)) * dq / (t - t0))
            mids.append(0.5 * (t0 + t))
        self.velocityless_skipped_ += skipped
        for name in names:
            self._joint_last[name] = t
        if names:
            # one entry per sample; its stamp is the midpoint of its joints' intervals
            zero = not any(taus)
            self._push_joint((float(np.mean(mids)), tuple(names), np.array(power), True, zero))
            self.joint_power_samples_ += 1
            self.zero_effort_samples_ += zero

    def add_odometry(self, sample: OdometrySample) -> None:
        """Add an odometry pose (horizontal position in the odometry frame, for the speed) and
        its twist's horizontal speed (for estimators that publish the velocity only, with the
        pose left at zero)."""
        if not self._clk.observe('odom', sample.t_s):
            return
        v = np.asarray(sample.linear_velocity_mps, dtype=float)
        speed = float(math.hypot(v[0], v[1])) if v.size >= 2 and np.all(np.isfinite(v[:2])) \
            else math.nan
        self._odom.append((sample.t_s, float(sample.position_m[0]),
                           float(sample.position_m[1]), speed))

    def add_pose(self, sample: PoseSample) -> None:
        """Add a body pose (position used for the speed).

        The speed is the body's displacement over whole gait cycles in all three axes: the
        height returns to itself after a whole cycle, so this is the horizontal speed in any
        motion-capture frame, z-up (Vicon, ROS) or y-up (OptiTrack), where the x-y distance
        read only part of a y-up frame's travel.
        """
        if not self._clk.observe('mocap/body', sample.t_s):
            return
        p = sample.position_m
        pose = (float(p[0]), float(p[1]), float(p[2]))
        if not all(math.isfinite(x) for x in pose):
            # a bridge publishing NaN while the body is lost: NaN speed, CoT and specific
            # resistance were published in 2 windows of 5, silently (an outside review)
            self.nonfinite_poses_ += 1
            if self.nonfinite_poses_ == 1:
                self.notes_.append(NONFINITE_POSE_NOTE)
            return
        if self._poses and self._poses[-1][1:] == pose:
            # a pose repeated to the last bit: a bridge repeating its last pose after losing
            # the body (real tracking noise never repeats); its new stamp would read as the
            # body standing still
            self.repeated_poses_ += 1
            return
        self._poses.append((sample.t_s, *pose))
        self._mocap_seen = True

    def add_gait_phase(self, sample: GaitPhaseSample) -> list[Descriptors]:
        """Add a gait schedule sample; a wrap of the cycle phase marks a cycle boundary."""
        if not self._clk.observe('gait/phase', sample.t_s):
            return []
        self._check_battery_quiet(sample.t_s)
        self._gait_hist.append(sample)
        if self.cycle_source == 'joints':
            self._gait = sample
            return []
        if not self._seen_gait:
            self._seen_gait = True
            if self._tracker is not None:  # auto: the schedule takes over from the joints
                self._tracker = None
                self._boundaries = []
                self._window_start = None
        self._gait = sample
        first = self._ref_gait is None
        why = self._schedule_break(sample)
        if first or why:
            self._check_feasible(sample)
        if why:
            # no window spans it: the one in progress is dropped, the next starts at the
            # next wrap of the new schedule; a standing stretch starts here (its windows
            # count from it; the last one before a break is dropped like a walking cycle's,
            # it would be read with the next schedule's speed)
            self._boundaries.append(math.nan)
            self.schedule_breaks_.append((sample.t_s, why))
            self._ref_gait = sample
            if sample.period_s <= 0:
                self._stand_anchor = sample.t_s
                self._boundaries.append(sample.t_s)
        elif self._last_phase is not None and sample.period_s <= 0 and \
                sample.t_s > self._last_phase[0]:
            # standing (period 0): no cycle wraps; windows of STAND_WINDOW_S from the start of
            # the standing, so the standing robot's input power (basal electronics and the
            # servos holding the body) is measured too, with speed 0 (CoT undefined)
            self._stand_boundaries(sample.t_s)
        elif self._last_phase is not None:
            t_prev, phase_prev = self._last_phase
            if sample.t_s > t_prev and sample.cycle_phase < phase_prev - 0.5:
                # interpolate the wrap instant between the two samples
                dphase = (1.0 - phase_prev) + sample.cycle_phase
                frac = (1.0 - phase_prev) / dphase if dphase > 0 else 1.0
                self._boundaries.append(t_prev + frac * (sample.t_s - t_prev))
        if self._last_phase is None or sample.t_s > self._last_phase[0]:
            self._last_phase = (sample.t_s, sample.cycle_phase)
        return self._emit()

    def _check_feasible(self, sample: GaitPhaseSample) -> None:
        """Note (once per schedule) a schedule the robot cannot walk (see ``limits``)."""
        key = (sample.gait, tuple(sample.leg_names), round(sample.period_s, 4),
               round(sample.duty_factor, 4), round(sample.step_length_m, 4),
               round(sample.step_height_m, 4))
        if key in self._checked or not sample.period_s > 0:
            return
        self._checked.add(key)
        from hexapod_gait.errors import HexapodGaitError
        from hexapod_gait.feasibility import ANTBOT_LIMITS

        from hexapod_energy.prediction import geometry_limits
        from hexapod_energy.recommend import infeasible_schedule

        class _Robot:   # the robot's leg; the limits carry their own step and leg
            bench_leg_ = self.leg

        try:
            gait = gait_from_sample(sample)
            bad = infeasible_schedule(gait, geometry_limits(
                _Robot(), gait, self.limits if self.limits is not None else ANTBOT_LIMITS))
        except (HexapodGaitError, ValueError) as err:
            self.notes_.append(f'gait schedule at {sample.t_s:.3f} s not checked against '
                               f'the actuator limits: {err}')
            return
        if bad:
            self.infeasible_.append((sample.t_s, bad))
            self.notes_.append(
                f'infeasible gait schedule from {sample.t_s:.3f} s ({sample.gait}, period '
                f'{sample.period_s:.4g} s, duty factor {sample.duty_factor:.4g}, step '
                f'{1e3 * sample.step_length_m:.4g} mm), not a gait the robot can walk: '
                + '; '.join(bad) + ' (its windows are still computed)')

    #: window length [s] while the schedule stands still (period 0): no cycle to average over
    STAND_WINDOW_S = 1.0

    def _stand_boundaries(self, t_s: float) -> None:
        """Standing-window boundaries from the last /gait/phase sample up to ``t_s``:
        multiples of STAND_WINDOW_S from the standing's start (``_stand_anchor``)."""
        assert self._last_phase is not None
        anchor = self._stand_anchor if self._stand_anchor is not None else 0.0
        w = self.STAND_WINDOW_S
        k_prev = math.floor((self._last_phase[0] - anchor) / w + 1e-9)
        k_now = math.floor((t_s - anchor) / w + 1e-9)
        self._boundaries.extend(anchor + w * k for k in range(k_prev + 1, k_now + 1))

    #: a schedule value (period, duty factor, step length) moving by more than this fraction
    #: from the one the windows started under breaks them (a transition, a new command)
    SCHEDULE_CHANGE = 0.02
    #: a /gait/phase silence longer than this [s] (and than half the period) breaks them
    SCHEDULE_GAP_S = 0.25

    def _schedule_break(self, sample: GaitPhaseSample) -> str:
        """Why no window may span this /gait/phase sample ('' when one may): a silence on
        the topic (a gait node stopped and started again), another gait or leg set, or a
        period, duty factor or step length that moved by more than :attr:`SCHEDULE_CHANGE`
        from the schedule the windows started under (a transition). A window across a gait
        node's restart mixed two schedules and was given the new one's speed (CoT/M 42 for
        the two gaits' 99 and 75); a window during a transition took its end's speed (+24 %).
        """
        ref = self._ref_gait
        if ref is None:
            self._ref_gait = sample
            return ''
        if self._last_phase is not None:
            gap = sample.t_s - self._last_phase[0]
            if gap > max(self.SCHEDULE_GAP_S, 0.5 * max(ref.period_s, 0.0)):
                return f'/gait/phase silent for {gap:.3f} s'
        if sample.gait != ref.gait or tuple(sample.leg_names) != tuple(ref.leg_names):
            return f'gait {ref.gait} -> {sample.gait}'
        for name in ('period_s', 'duty_factor', 'step_length_m'):
            a, b = float(getattr(ref, name)), float(getattr(sample, name))
            if abs(b - a) > self.SCHEDULE_CHANGE * max(abs(a), abs(b), 1e-9):
                return f'{name} {a:.4g} -> {b:.4g}'
        return ''

    # -- windows ---------------------------------------------------------------------------
    def _emit(self) -> list[Descriptors]:
        out = []
        while True:
            if self._window_start is None:
                if not self._boundaries:
                    return out
                self._window_start = self._boundaries.pop(0)
                if math.isnan(self._window_start):  # a break of the joint-derived cycles
                    self._window_start = None
                    continue
            if len(self._boundaries) < self.cycles or not self._battery:
                return out
            breaks = [k for k, b in enumerate(self._boundaries[:self.cycles]) if math.isnan(b)]
            if breaks:  # no window spans a break in the joint-derived cycles
                self._window_start = None
                del self._boundaries[:breaks[0] + 1]
                continue
            t0, t1 = self._window_start, self._boundaries[self.cycles - 1]
            if self._battery[-1][0] < t1 or self._battery[0][0] > t0:
                if self._battery[0][0] > t0:  # window starts before the first battery sample
                    self._window_start = None
                    self._boundaries = self._boundaries[self.cycles - 1:]
                    continue
                return out
            if (self._joints_pending(t1) or self._poses_pending(t1)) and \
                    self._battery[-1][0] < t1 + JOINT_WAIT_S:
                return out
            out.append(self._window(t0, t1))
            self._recheck_sign(out[-1])
            self._window_start = t1
            del self._boundaries[:self.cycles]
            self._trim(t1)

    def _recheck_sign(self, d: Descriptors) -> None:
        """``current_sign`` auto decides on the first samples; a robot that starts on its
        charger (charging current, positive in the ROS convention) got the wrong sign and
        read negative power for the whole run, warned per window (an outside review). After
        :data:`AUTO_RECHECK_WINDOWS` windows in a row of mean power at or below -1 W, when
        most battery samples since the decision (of those beyond +-1 W) contradict it too, the
        sign is decided again: flipped, noted; the windows already computed stand."""
        if self.current_sign != 'auto' or self.sign_ is None:
            return
        negative = d.power_in_w <= -AUTO_UNANIMOUS_MIN_W
        self._negative_run = self._negative_run + 1 if negative else 0
        agree, against = self._sign_votes
        # a few negative windows alone are not enough (a robot regenerating downhill or set
        # on its charger for a while, a standing robot's sensor offset: a second review);
        # most of the samples since the decision must contradict it too
        if self._negative_run < AUTO_RECHECK_WINDOWS or against <= agree:
            return
        self._negative_run = 0
        self._sign_votes = [against, agree]
        self.sign_ = -self.sign_
        self._battery = [(t, -p) for t, p in self._battery]
        self.sign_note_ = ''
        self.notes_.append(
            f'{AUTO_RECHECK_WINDOWS} windows in a row with negative mean input power: the '
            'battery current sign decided on the first samples (a robot starting on its '
            'charger?) is flipped, now ' + ('the ROS convention (negative while discharging)'
                                            if self.sign_ < 0 else 'positive while '
                                            'discharging') + '; give -p current_sign to fix it')

    def _joints_pending(self, t1: float) -> bool:
        """Whether a joint that gave power within :data:`JOINT_WAIT_S` before ``t1`` has no
        sample at or after ``t1`` yet: its samples inside the window may still be on their
        way. Joint states commonly arrive after the battery sample that passes the window's
        end (a servo bus read behind a USB adapter; one message per leg, in no fixed order
        across topics); a window closed then averaged only the part of its cycle received,
        P_out -5.8 % with a 50 ms lag (an outside review). The offline readers feed samples
        in stamp order and never wait."""
        if self.power_out_source == 'model' or not self._joint_last:
            return False
        return any(t1 - JOINT_WAIT_S <= t < t1 for t in self._joint_last.values())

    def _poses_pending(self, t1: float) -> bool:
        """Whether motion capture that gave a pose within :data:`JOINT_WAIT_S` before ``t1``
        has none at or after ``t1`` yet: the window's speed is the body's displacement
        interpolated at its bounds, which needs the pose after ``t1`` (waited for like late
        joint states, so live and offline windows agree)."""
        if not self._poses:
            return False
        last = max(p[0] for p in self._poses[-8:])
        return t1 - JOINT_WAIT_S <= last < t1

    def _gait_at(self, t: float) -> GaitPhaseSample | None:
        """The /gait/phase sample in force at ``t``: the last one stamped at or before it
        (the latest one when none is)."""
        for g in reversed(self._gait_hist):
            if g.t_s <= t:
                return g
        return self._gait

    def _model_power_out(self, gait: Any, warnings: list[str]) -> float:
        """The Eq. 6 model's P_out for the window's schedule, NaN with the reason when the
        model cannot take that schedule (legs named outside the contract's L1..Lk / R1..Rk:
        the live node dropped every battery sample on it and gave no window, where the
        offline command gave P_in with P_out null: an outside review)."""
        shape = model_leg_mismatch(sorted(self._joint_names_seen))
        if shape:
            warnings.append(f'no P_out model for these legs: the Eq. 6 model\'s leg has the '
                            f'joints {", ".join(MODEL_LEG_JOINTS)}, /joint_states names others '
                            f'({shape}); P_out unknown (NaN) without usable joint efforts')
            return math.nan
        try:
            return float(self.power_out_model(gait, self.mass_kg))
        except ValueError as err:
            warnings.append(f'no P_out model for this schedule: {err}; P_out unknown (NaN)')
            return math.nan

    def _window(self, t0: float, t1: float) -> Descriptors:
        gait = self._gait_at(t1)
        warnings: list[str] = []
        t = np.array([b[0] for b in self._battery])
        p = np.array([b[1] for b in self._battery])
        order = np.argsort(t, kind='stable')
        t, p = t[order], p[order]
        power_in = span_mean(t, p, t0, t1)
        # a gap much longer than the stream's own interval means P_in was interpolated
        # across missing data. Checked for windows with few samples too: a window wholly
        # inside a gap holds none, and was taken for a slow monitor's (a 5 s gap in a 15 s
        # AntBot bag: 7 windows interpolated between the gap's ends, 31.6 W for 35.0 W)
        gap = t.size >= 2 and _gap_in_window(t, t0, t1, self._battery_steps or np.diff(t))
        if gap:
            warnings.append(BATTERY_GAP_NOTE)
        elif int(np.count_nonzero((t > t0) & (t < t1))) < MIN_BATTERY_SAMPLES_PER_WINDOW:
            warnings.append(SLOW_BATTERY_NOTE)
        if power_in < 0:
            warnings.append(f'negative mean input power {power_in:.3f} W: check the battery '
                            'current sign convention (parameter current_sign)')
        joint = [j for j in self._joint if t0 <= j[0] < t1]
        if self.power_out_source != 'model' and self._joint_gap(t0, t1):
            # a window inside or across a /joint_states gap: its P_out from the efforts
            # would cover part of it (a 2 s gap in a 5.4 s EduBot bag took the run's P_out
            # from 11.3 to 8.5 W: the empty windows counted 0 W)
            warnings.append(JOINT_GAP_NOTE)
        if joint and gait is not None:
            # every joint the window's messages name: a driver publishing one JointState per
            # leg had the last message's 3 joints compared, and 5 legs of 6 called missing on
            # every window (an outside live review)
            names = sorted({n for j in joint for n in j[1]})
            missing = _legs_without_joints(gait.leg_names, names)
            if missing:
                warnings.append(f'{LEG_MISMATCH_NOTE}: the gait schedule names legs '
                                f'{", ".join(missing)} that have no '
                                f'joint on /joint_states ({len(names)} joints): the gait '
                                'node and the robot disagree on the legs (leg_count?)')
            extra = _joint_legs_outside(gait.leg_names, names)
            if extra:
                warnings.append(f'{LEG_MISMATCH_NOTE}: legs {", ".join(extra)} have joints '
                                'on /joint_states that '
                                f'the gait schedule ({len(gait.leg_names)} legs) does not name: '
                                'the gait node walks fewer legs than the robot has, and those '
                                'stand (leg_count?)')
        # a Buehler clock (RHex-class legs turning, no step length): the Eq. 6 model is for
        # stepping legs (it gave 0 W), and a turning leg does little negative work, so the
        # PWM-load test is not for it (live EduBot windows read P_out 0 W in 12 of 17, the
        # offline command 11.6 W from the same efforts: an outside review)
        clock = gait is not None and is_clock_schedule(gait)
        has_model = self.power_out_model is not None and gait is not None and not clock
        zero_effort = bool(joint) and all(j[4] for j in joint) and \
            self.power_out_source != 'model'
        if zero_effort:
            # efforts all 0.0 (no effort interface): as without efforts, P_out unknown when
            # no model gives it (P_out 0 W and efficiency 0 passed every test: net / positive
            # joint power is 0 / 0)
            warnings.append(ZERO_EFFORT_NOTE + (
                '; P_out from the Eq. 6 model' if has_model and self.power_out_source == 'auto'
                else '; P_out unknown (NaN)'))
            joint = []
        use_model = self.power_out_source == 'model' or \
            (self.power_out_source == 'auto' and not joint)
        joint_path = self.joint_cycles_
        # the joint units the samples so far say: velocities in a unit recognised (deg/s,
        # rpm, rev/s) and positions in degrees are converted to rad/s and rad (P_out 57x from
        # deg/s velocities, 8.5x from rpm); a factor of no unit (a gear ratio) is refused
        units = self.joint_units_()
        if joint and units.refused:
            warnings.append(units.note)
        elif joint and units.note:
            key = f'{units.velocity_unit} {units.position_factor:g}'
            if key not in self._units_said:   # said once (the node logs it), not per window
                self._units_said.add(key)
                self.notes_.append(units.note)
        if joint and (units.velocity_factor != 1.0 or units.position_factor != 1.0):
            joint = [(j[0], j[1], j[2] / (units.position_factor if j[3]
                                          else units.velocity_factor), j[3], j[4])
                     for j in joint]
        net = _mean_joint_power_w(joint, signed=True) if joint else math.nan
        from_model = False
        if joint and self.power_out_source != 'model':
            power_out = _mean_joint_power_w(joint)
            if any(j[3] for j in joint):
                warnings.append(POSITION_POWER_NOTE)
            why = ('' if self.power_out_source != 'auto' else
                   'P_out from effort x velocity refused (velocities not rad/s)'
                   if units.refused else
                   implausible_effort_power(power_out, power_in, math.nan if clock else net))
            if why:
                warnings.append(why + ('; P_out from the Eq. 6 model' if has_model else
                                       '; P_out unknown (NaN)'))
                power_out = (self._model_power_out(gait, warnings)
                             if has_model else math.nan)
                from_model = has_model
        elif use_model and has_model:
            power_out = self._model_power_out(gait, warnings)
            from_model = True
        elif use_model and clock and self.power_out_model is not None:
            warnings.append(CLOCK_MODEL_NOTE)
            power_out = math.nan
        elif joint_path:
            warnings.append(('no joint efforts in the window'
                             if self.power_out_source != 'model' else 'power_out_source is model')
                            + ': P_out unknown (NaN); the Eq. 6 model needs the gait schedule '
                            '(/gait/phase)')
            power_out = math.nan
        else:
            if self.power_out_source == 'model':
                warnings.append('power_out_source is model but no model or gait schedule: '
                                'P_out = 0')
            power_out = math.nan if zero_effort else 0.0
        speed, speed_source = self._speed_and_source(t0, t1, gait, warnings)
        if speed_source == 'gait_schedule' and gait is not None and speed > MAX_SPEED_MPS:
            # a step length in mm walked at 160 m/s: CoT/M and SR 1000x low, silently
            warnings.append(schedule_speed_note(gait))
            speed, speed_source = math.nan, 'none'
        # (a stand of a stepping gait, step length and height 0 and no clock sweep, is not
        # walking; a Buehler clock's legs turn)
        stand = gait is not None and gait.gait != 'buehler' and not (
            gait.step_length_m > 0 or gait.step_height_m > 0 or gait.sweep_angle_rad > 0)
        if gait is not None and (gait.step_length_m > 0 or clock) and not stand:
            moved = self._joint_motion_rad(t0, t1, float(gait.period_s))
            if moved is not None:   # positions in degrees: their range in radians
                moved /= units.position_factor
            if moved is not None and moved < STILL_JOINTS_RAD:
                # the schedule's speed and the Eq. 6 model are a walking robot's: a robot
                # standing still read 0.15 m/s, specific resistance 2.85 for 6.93 walking
                # (an outside review: its joint_commands remapped away, and a simulator
                # that took the commands 2.2 s late)
                warnings.append(f'{STILL_JOINTS_NOTE}: largest joint range {moved:.4f} rad')
                if speed_source == 'gait_schedule':
                    speed, speed_source = math.nan, 'none'
                if from_model:
                    power_out = math.nan
        out_source = ('none' if not math.isfinite(power_out) else 'model' if from_model
                      else 'effort' if joint and self.power_out_source != 'model' else '')
        return descriptors_from_powers(power_in_w=power_in, power_out_w=power_out,
                                       speed_mps=speed, mass_kg=self.mass_kg,
                                       window_s=t1 - t0, t_end_s=t1, cycles=self.cycles,
                                       warnings=tuple(warnings), speed_source=speed_source,
                                       cycle_source='joints' if joint_path else 'gait_phase',
                                       joint_power_net_w=net, power_out_source=out_source)

    def _joint_motion_rad(self, t0: float, t1: float, period_s: float = 0.0) -> float | None:
        """The largest position range [rad] of any leg joint over the window, None without
        positions in it; infinite when a joint velocity says it moved (positions a driver
        leaves constant)."""
        lo: dict[str, float] = {}
        hi: dict[str, float] = {}
        seen: dict[str, list[float]] = {}
        for t, names, pos, speed in self._leg_pos:
            if not t0 <= t <= t1:
                continue
            if speed > STILL_JOINTS_RAD_S:
                return math.inf   # reported moving (a driver that fills no positions)
            for name, q in zip(names, pos):
                if math.isfinite(q):
                    lo[name] = min(q, lo.get(name, q))
                    hi[name] = max(q, hi.get(name, q))
                    seen.setdefault(name, []).append(t)
        # samples at too few phases of the gait cycle cannot show a still joint: one sample
        # per cycle reads a range of 0 on a walking robot (a review: joint states at 1 Hz
        # without velocities, every window of a walking run left out); a fixed sample count
        # missed a still robot at an AX-18A bus's 11 Hz (another review)
        cycle = period_s if period_s > 0 else (t1 - t0)
        judged = [n for n, ts in seen.items()
                  if len({int(((t - t0) / cycle % 1.0) * STILL_PHASE_BINS) for t in ts})
                  >= STILL_MIN_PHASES]
        if not judged:
            return None
        return max(hi[n] - lo[n] for n in judged)

    def _speed(self, t0: float, t1: float) -> float:
        """Speed [m/s] over the window."""
        return self._speed_and_source(t0, t1)[0]

    def _speed_and_source(self, t0: float, t1: float, gait: GaitPhaseSample | None = None,
                          notes: list[str] | None = None) -> tuple[float, str]:
        """Speed [m/s] over the window and its source.

        A clock-driven schedule (the Buehler clock of RHex-class robots: step length 0 while
        the legs turn, so ``speed_mps`` 0) does not know the speed: it is not taken as 0 m/s
        (which used to average the EduBot's 0.88 m/s with zeros outside the mocap volume);
        odometry, the given speed, or unknown (NaN) stand in for it.

        Motion capture over part of the window (an occlusion) gives the speed as
        :func:`_track_speed` says, with a warning in ``notes``; a window it gives no speed
        (after poses came) falls back to the next source with a warning naming it (it used to
        in silence: +25 % specific resistance in one window of five, an outside review).
        """
        if gait is None:
            gait = self._gait
        lost = ''
        schedule = gait is not None and (gait.speed_mps > 0 or gait.period_s <= 0)
        for source, track in (('mocap', self._poses), ('odometry', self._odom)):
            poses = sorted(p for p in track if t0 <= p[0] <= t1)
            if source == 'odometry' and schedule:
                # the schedule ranks before odometry (the paper's v = step / (beta T); an
                # odometry is often the same kinematics integrated); a disagreement is kept
                assert gait is not None
                v_sched = gait.speed_mps
                if len(poses) >= 2 and v_sched > 0 and poses[-1][0] > poses[0][0]:
                    d = [b - a for a, b in zip(poses[0][1:3], poses[-1][1:3])]
                    v_odom = math.hypot(*d) / (poses[-1][0] - poses[0][0])
                    twist = np.array([p[3] for p in poses], dtype=float)
                    twist = twist[np.isfinite(twist)]
                    if v_odom < ODOM_STILL_MPS and twist.size:   # a velocity-only odometry
                        v_odom = float(np.mean(twist))
                    if abs(v_odom - v_sched) > ODOM_DISAGREE * v_sched:
                        self.odometry_disagreements_.append((v_sched, v_odom))
                if lost and notes is not None:
                    notes.append(lost + '; speed from the gait schedule (step_length / '
                                 '(duty_factor x period))')
                return v_sched, 'gait_schedule'
            n = 3 if source == 'mocap' else 2
            speed, why = _track_speed(track, t0, t1, n) if track else (None, '')
            if speed is None:
                if source == 'mocap' and self._mocap_seen:
                    inside = [p[0] for p in track if t0 <= p[0] <= t1]
                    cover = (max(inside) - min(inside)) / (t1 - t0) if inside else 0.0
                    if cover >= POSE_MIN_COVER:
                        # _track_speed leaves out a window the body enters the volume in
                        # (no pose before it); it had been called "under 50 %" at 54 %
                        lost = (f'{POSE_FALLBACK_NOTE}: the body entered the motion-capture '
                                f'volume {min(inside) - t0:.3f} s after its start (its poses '
                                f'span {100 * cover:.0f} % of it; not a whole window of '
                                'motion)')
                    else:
                        lost = (f'{POSE_FALLBACK_NOTE}: its poses span {100 * cover:.0f} % of '
                                f'it (under {100 * POSE_MIN_COVER:.0f} %; the body lost by the '
                                'motion capture?)')
                continue
            if source == 'odometry':
                twist = np.array([p[3] for p in poses])
                twist = twist[np.isfinite(twist)]
                if speed < ODOM_STILL_MPS and twist.size and \
                        float(np.mean(twist)) > ODOM_STILL_MPS:
                    # a velocity-only estimator: the pose stays at 0, the twist moves
                    return float(np.mean(twist)), 'odometry_twist'
            if why and notes is not None:
                notes.append(why)
            return speed, source
        if self.speed_mps > 0:
            speed, source = self.speed_mps, 'given'
        else:
            speed, source = (math.nan if self.joint_cycles_ or gait is not None else 0.0), \
                'none'
        if lost and notes is not None:
            notes.append(lost + f'; speed from {_SPEED_SOURCE_NAMES.get(source, source)}')
        return speed, source

    def _trim(self, t: float, *, keep_s: float = 1.0) -> None:
        keep_from = t - keep_s
        last_before = [b for b in self._battery if b[0] <= t]
        self._battery = ([last_before[-1]] if last_before else []) + \
            [b for b in self._battery if b[0] > t]
        self._joint = [j for j in self._joint if j[0] >= keep_from]
        self._leg_pos = [j for j in self._leg_pos if j[0] >= keep_from]
        self._poses = [p for p in self._poses if p[0] >= keep_from]
        older = [k for k, g in enumerate(self._gait_hist) if g.t_s <= keep_from]
        if older:   # keep the last one at or before keep_from: it is in force there
            del self._gait_hist[:older[-1]]
        self._odom = [p for p in self._odom if p[0] >= keep_from]
