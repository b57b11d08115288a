"""``slip_fitter`` node: one ``SlipFit`` on ``/slip/fit`` for every stance as soon as it ends.

Subscribes ``/joint_states`` and ``/joint_commands`` (hip speeds; the commanded speeds are the
Buehler target), ``/mocap/body`` (PoseStamped, or the type named by the ``mocap_type``
parameter); the science is in :class:`slip_identification.online.OnlineSlip`. Fits run on the
first mocap message after a lift-off (plus ``margin`` seconds, default 0). With a finite
``ground`` parameter the stance windows are the half-circle legs' geometric contacts (hip
angles from ``/joint_states`` positions; ``leg_radius``, ``hip_x`` describe the robot, EduBot by
default); without it the node warns at startup that its fits will differ from
``hexapod-analyze slip``'s (clock edges, no stream-offset estimate) and how to get the
parameters (that command prints them). Joint states
split over several messages, hip angles wrapped into ``[-pi, pi)`` or ``[0, 2 pi)``, and
positions without velocities (speeds from central differences, one joint-state period of
extra latency) are handled by the core; each such fallback is logged once (info). Time going
back by more than a second (a looped bag, a simulation clock reset) is logged once per jump
as a warning, and stance detection restarts from the new time. Messages missing from
``/joint_states`` or ``/mocap/body`` (gaps in their stamps: a lossy link, or the node behind
its input, whose oldest queued messages the DDS history overwrites) are counted
(``loss.missing``) and logged on the topic's 1st, 10th, 100th ... missing message. Stances
not fitted (before the world frame is ready, outside the box, too short, cut by a
motion-capture gap) are counted by reason (``skipped_counts``) and logged on each reason's
1st, 10th, 100th ... stance.
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('slip_fitter')

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from hexapod_common.clocks import LiveClockWatch, StreamLoss
from hexapod_common.conversions import (
    MOCAP_TYPES,
    LegJointFilter,
    joint_state_from_msg,
    pose_from_msg,
    s_to_stamp,
)
from hexapod_common.node_utils import (
    RELIABLE_QOS,
    SENSOR_QOS,
    InputWatch,
    declare_params,
    mocap_msg_class,
    param,
    run_node,
)
from hexapod_interfaces.msg import SlipFit

from .calibration import CALIBRATION_STRIDES, Calibration, SelfCalibration, calibrate
from .errors import SlipError
from .fit import SlipFitResult
from .geometry import LegGeometry
from .model import SlipModel
from .online import OnlineSlip
from .stamps import LiveRepeatedStamps, repeat_note
from .pipeline import rotate_body
from .preprocess import Box

__all__ = ['SlipFitterNode', 'SlipParams', 'clock_edges_warning', 'main', 'result_to_msg',
           'startup_notes']

#: leg joint states without any ``<leg>_hip`` joint after which that is warned (once)
HIPLESS_MESSAGES = 50

#: distinct drop reasons counted separately; beyond them, one shared count
MAX_DROP_REASONS = 64


#: what each reason of :attr:`OnlineSlip.skipped` means, for the log
SKIP_REASONS = {
    'frame_not_ready': 'before the world frame was ready (it needs half a second of motion '
                       'capture in the box)',
    'outside_volume': 'under 10 motion-capture samples inside the box (parameter box)',
    'too_short': 'shorter than the shortest stance fitted (or too few motion-capture samples '
                 'in it)',
    'mocap_gap': 'a motion-capture gap cuts it',
    'nan': 'NaN or inf in its motion capture',
}


def _positive(v: float) -> str | None:
    return None if v > 0 else 'must be > 0'


def _non_negative(v: float) -> str | None:
    return None if v >= 0 else 'must be >= 0'


def _model_name(v: str) -> str | None:
    try:
        SlipModel.from_name(v)
    except (SlipError, ValueError) as err:
        return str(err)
    return None


def _box(v: list[float]) -> str | None:
    if len(v) != 6:
        return f'expected 6 values (x0 y0 z0 x1 y1 z1), got {len(v)}'
    if not all(lo < hi for lo, hi in zip(v[:3], v[3:])):
        return 'expected each lower corner value below the upper one'
    return None


@dataclass(frozen=True)
class SlipParams:
    mass: float = param(3.31, 'robot mass m [kg]; a run-time change applies to the next fits',
                        validate=_positive)
    model: str = param('slip', "template: 'slip' or 'slip+leg_damping' etc.",
                       validate=_model_name, read_only=True)
    starts: str = param('multi', "the fits' Nelder-Mead starts: multi (the paper's and the "
                        "stance's own scales, the lowest nerr kept) or paper (its start alone)",
                        validate=lambda v: None if v in ('multi', 'paper')
                        else "expected 'multi' or 'paper'", read_only=True)
    mocap_offset: float = param(math.nan, 'seconds subtracted from mocap stamps (stream '
                                'offset); NaN (default): self-calibrated without ground, else 0',
                                read_only=True, finite=False,
                                validate=lambda v: None if not math.isinf(v)
                                else 'expected seconds or NaN')
    margin: float = param(0.0, 'mocap needed after lift-off before fitting [s] (0: the '
                          'first sample after lift-off); a run-time change applies at once',
                          validate=_non_negative)
    box: list[float] = param([-1.0, -0.5, -0.5, 1.0, 0.5, 0.5],
                             'permissible box in the mocap frame x0 y0 z0 x1 y1 z1 [m]',
                             validate=_box, read_only=True)
    ground: float = param(math.nan, 'ground height in the world frame [m] (e.g. an offline '
                          "analysis' ground_m); finite: geometric stance edges from the "
                          'half-circle legs, NaN: self-calibrated (calibration_strides), or '
                          "the paper's clock edges", read_only=True, finite=False)
    pitch_offset: float = param(math.nan, "the motion-capture rigid body's pitch zero against "
                                'the hip line [deg] (an offline slip analysis\' '
                                'runs[].frame.pitch_offset_deg; geometric edges); NaN (default): '
                                'self-calibrated without ground, else 0', read_only=True,
                                finite=False,
                                validate=lambda v: None if math.isnan(v) or abs(v) <= 45.0
                                else 'expected a value within +-45 deg (or NaN)')
    calibration_strides: float = param(
        CALIBRATION_STRIDES, 'without ground: strides of motion capture in the box buffered '
        'before the ground, stream offset and pitch zero are estimated from them by '
        "`hexapod-analyze slip`'s estimators (the buffered stances then fitted and published); "
        "0: no self-calibration (the paper's clock edges)", read_only=True,
        validate=lambda v: None if v >= 0 else 'must be >= 0')
    leg_radius: float = param(LegGeometry.leg_radius_m, 'arc radius R of the half-circle '
                              'leg [m] (geometric edges)', validate=_positive, read_only=True)
    hip_x: list[float] = param(list(LegGeometry.hip_x_m), 'hip x front, middle, rear from '
                               'the COM [m] (geometric edges)', read_only=True,
                               validate=lambda v: None if len(v) == 3 else
                               f'expected 3 values (front, middle, rear), got {len(v)}')
    hip_signs: list[float] = param(
        [1.0] * 6, 'sign of each hip angle, L1 L2 L3 R1 R2 R3 (-1: the motor is mounted '
        'mirrored and reports forward rotation negative; the offline slip analysis detects it '
        'and prints the value to use here)',
        validate=lambda v: None if len(v) == 6 and all(x in (1.0, -1.0) for x in v)
        else 'expected 6 values, each 1 or -1', read_only=True)
    body_up: str = param(
        'z', "the motion-capture rigid body's axis that points up (z, x, y, -x, -y, -z; the "
        'offline slip analysis names it when the rigid body is defined otherwise)',
        validate=lambda v: None if v in ('z', 'x', 'y', '-x', '-y', '-z')
        else 'expected z, x, y, -x, -y or -z', read_only=True)
    mocap_type: str = param(
        'PoseStamped', 'message type of mocap/body: PoseStamped (the contract), '
        'TransformStamped (vicon_bridge), PoseWithCovarianceStamped or Odometry',
        validate=lambda v: None if v in MOCAP_TYPES else f'expected one of {list(MOCAP_TYPES)}',
        read_only=True)
    input_timeout_s: float = param(
        5.0, 'wall time [s] without messages on joint_states or on mocap/body after which '
        'that is warned, each (0: off)', read_only=True,
        validate=lambda v: None if math.isfinite(v) and v >= 0 else 'expected >= 0 s')


#: what ``hexapod-analyze slip`` gives the live node, in the startup warning
REMEDY = ('record a few seconds of the gait, run `hexapod-analyze slip BAG --out DIR` and pass '
          'the values it prints on its "live slip_fitter" line (DIR/slip.json: '
          'runs[].ground_m, runs[].offset_s, runs[].frame.pitch_offset_deg): -p ground:=G '
          '-p mocap_offset:=S -p pitch_offset:=DEG')


def clock_edges_warning(p: SlipParams) -> str:
    """The warning of a node without ground and without self-calibration: its fits differ
    from the offline analysis', and how to get the parameters."""
    offset = ('there is no stream offset (mocap_offset 0 s; the node does not estimate '
              'it)' if not math.isfinite(p.mocap_offset) or p.mocap_offset == 0.0
              else f'the stream offset is the given {p.mocap_offset:g} s')
    return ("the stance edges are the paper's shifted clock edges, not the legs' geometric "
            'contacts `hexapod-analyze slip` uses, and ' + offset + '; on a simulated EduBot '
            'run this made the fitted stiffness 35-71 % low and the rest length 25 % long '
            'against the offline analysis. For fits that agree with it, ' + REMEDY)


def startup_notes(p: SlipParams) -> list[tuple[str, str]]:
    """``(log level, text)`` said once at startup about the parameters. Without ``ground``
    the node calibrates itself (:mod:`.calibration`; said as info), or, with
    ``calibration_strides`` 0, its stance edges are the paper's clock edges and the stream
    offset is not estimated (a warning: an outside review replaying a simulated EduBot
    running bag: stiffness 35-71 % low, median 3989 against 11084 N/m offline, rest length
    0.131 against 0.105 m, nerr 0.127 against 0.059; with the offline ground, offset and
    pitch 12 of 12 stances within 2 ms and k 10815 N/m). It had been said only in the
    README."""
    if not math.isfinite(p.ground):
        if p.calibration_strides > 0:
            kept = [n for n, v in (('mocap_offset', p.mocap_offset),
                                   ('pitch_offset', p.pitch_offset)) if math.isfinite(v)]
            return [('info', f'no ground given (parameter ground): the first '
                     f'{p.calibration_strides:g} strides of motion capture in the box are '
                     'buffered and the ground, stream offset and pitch zero estimated from '
                     "them by `hexapod-analyze slip`'s estimators"
                     + (f' ({", ".join(kept)} as given)' if kept else '')
                     + '; their stances are fitted and published once that is done, later '
                     'ones as they come (calibration_strides:=0 turns it off)')]
        return [('warning', 'no ground given (parameter ground) and no self-calibration '
                 '(calibration_strides 0): ' + clock_edges_warning(p))]
    if not math.isfinite(p.mocap_offset) or p.mocap_offset == 0.0:
        return [('info', 'mocap_offset is 0 s: the motion capture is taken as stamped on the '
                 'joint states\' clock (the node does not estimate the stream offset when '
                 'ground is given); otherwise ' + REMEDY)]
    return []


def result_to_msg(r: SlipFitResult) -> SlipFit:
    """SlipFitResult -> hexapod_interfaces/SlipFit (stamp = touchdown)."""
    msg = SlipFit()
    msg.header.stamp.sec, msg.header.stamp.nanosec = s_to_stamp(r.touchdown_s)
    msg.liftoff.sec, msg.liftoff.nanosec = s_to_stamp(r.liftoff_s)
    msg.tripod = r.tripod
    msg.model = r.model
    msg.stiffness = r.params['stiffness']
    msg.rest_length = r.params['rest_length']
    msg.foot_x = r.params['foot_x']
    msg.stiffness_stderr = r.stderr['stiffness']
    msg.rest_length_stderr = r.stderr['rest_length']
    msg.foot_x_stderr = r.stderr['foot_x']
    extra = [k for k in r.params if k not in ('stiffness', 'rest_length', 'foot_x')]
    msg.extra_names = extra
    msg.extra = [r.params[k] for k in extra]
    msg.nerr = r.nerr if math.isfinite(r.nerr) else float('nan')
    msg.samples = r.samples
    msg.converged = r.converged
    return msg


class SlipFitterNode(Node):
    """Thin node around :class:`OnlineSlip`."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('slip_fitter', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = declare_params(self, SlipParams, on_change=self._on_change)
        self._p = p
        b = list(p.box)
        self._box = Box(tuple(b[:3]), tuple(b[3:]))
        self._geometry = LegGeometry(
            hip_x_m=tuple(float(v) for v in p.hip_x),  # type: ignore[arg-type]
            leg_radius_m=p.leg_radius)
        self.core = self._new_core(p.ground if math.isfinite(p.ground) else None,
                                   p.mocap_offset, p.pitch_offset)
        for level, text in startup_notes(p):
            if level == 'info':   # one call site per severity (rclpy refuses a change)
                self.get_logger().info(text)
            else:
                self.get_logger().warning(text)
        #: the self-calibration without ground (None: off, or ground given); ``core`` is
        #: the clock-edge core until it hands over (:meth:`_take_calibration`)
        self.calibration: SelfCalibration | None = None
        self._calibration_warned = 0
        self._handed_over = 0   # fits the hand-over gave
        self._pending_said = ''   # the self-calibration not due, said at the end
        if not math.isfinite(p.ground) and p.calibration_strides > 0:
            self._calibration_ready = self.create_guard_condition(self._take_calibration)
            self.calibration = SelfCalibration(
                p.calibration_strides, self._calibrate_run, self._calibrated_core,
                box=self._box, on_ready=self._calibration_ready.trigger)
        # the compiled fit loaded now, not in the first stance's publish latency
        warm_s = (self._new_core(0.0, 0.0, 0.0) if self.calibration is not None
                  else self.core).warm_up()
        self.get_logger().debug(f'fit kernels loaded in {warm_s:.2f} s')
        self.pub = self.create_publisher(SlipFit, 'slip/fit', RELIABLE_QOS)
        js_sub = self.create_subscription(JointState, 'joint_states', self._on_js, SENSOR_QOS)
        self.create_subscription(JointState, 'joint_commands', self._on_cmd, SENSOR_QOS)
        mocap_sub = self.create_subscription(mocap_msg_class(p.mocap_type), 'mocap/body',
                                             self._on_mocap, SENSOR_QOS)
        #: joint states or motion capture that never come or stop: said on the wall clock
        self.inputs = InputWatch(self, {'joint_states': js_sub, 'mocap/body': mocap_sub},
                                 p.input_timeout_s, mode='each',
                                 consequence='no stance can be fitted')
        order = [f'{side}{k}_hip' for side in 'LR' for k in (1, 2, 3)]
        self._hip_sign = {n: -1.0 for n, v in zip(order, p.hip_signs) if v < 0}
        self._body_up = p.body_up
        self.published = 0
        self.received = 0
        self.dropped = 0
        self._drops: dict[str, int] = {}   # reason -> messages dropped for it
        self._warnings_logged = 0
        self._notes_logged = 0
        self._skips_logged = 0
        #: stances not fitted, by reason (:attr:`OnlineSlip.skipped`; logged by reason on
        #: its 1st, 10th, 100th ... stance)
        self.skipped_counts: dict[str, int] = {}
        self._clocks = LiveClockWatch()   # stamps against the node clock
        # a driver stamping with its last bus read repeats a stamp with new values: such a
        # sample is re-stamped from its arrival time, or dropped (as the offline reader does)
        self._repeats = LiveRepeatedStamps()
        self._leg_joints: dict[str, LegJointFilter] = {}   # a gripper beside the legs
        #: messages missing from joint_states and mocap/body, from their stamp gaps (a node
        #: behind its input loses the oldest queued ones without a word): logged on the 1st,
        #: 10th, 100th ... of a topic
        self.loss = StreamLoss()
        #: leg joint states seen without any ``<leg>_hip`` joint (None once a hip came)
        self._hipless: int | None = 0
        self._joint_names: set[str] = set()

    def _new_core(self, ground_m: float | None, offset_s: float,
                  pitch_offset_deg: float) -> OnlineSlip:
        """A core with this node's model, box, margin and starts; geometric edges when
        ``ground_m`` is given (NaN offsets and pitch zero: 0)."""
        p = self._p
        core = getattr(self, 'core', None)   # the current model and margin (run-time set)
        return OnlineSlip(core.model if core is not None else
                          SlipModel.from_name(p.model, mass_kg=p.mass),
                          box=self._box,
                          mocap_offset_s=offset_s if math.isfinite(offset_s) else 0.0,
                          margin_s=core.margin_s if core is not None else p.margin,
                          geometry=self._geometry if ground_m is not None else None,
                          ground_m=ground_m,
                          pitch_offset_rad=math.radians(pitch_offset_deg)
                          if math.isfinite(pitch_offset_deg) else 0.0,
                          starts=p.starts)

    def _calibrate_run(self, run: Any) -> Calibration:
        """The self-calibration's estimators on the buffered run (worker thread): those of
        ``hexapod-analyze slip`` with its defaults, this node's legs (another robot's legs
        with the EduBot damping time assumed and checked, as the command does), box and
        model; a given ``mocap_offset`` or ``pitch_offset`` kept."""
        p = self._p
        geo = self._geometry
        if geo.leg_radius_m != LegGeometry.leg_radius_m or \
                tuple(geo.hip_x_m) != tuple(LegGeometry.hip_x_m):
            geo = dataclasses.replace(geo, damping_assumed=True, damping_stiffness_n_m=None)
        else:
            geo = LegGeometry()
        return calibrate(run, geometry=geo, box=self._box, model=self.core.model,
                         offset_s=p.mocap_offset if math.isfinite(p.mocap_offset) else None,
                         pitch_offset_deg=(p.pitch_offset if math.isfinite(p.pitch_offset)
                                           else None),
                         check_body_up=p.body_up == 'z', starts=p.starts)

    def _calibrated_core(self, cal: Calibration) -> OnlineSlip:
        """The core the buffer is replayed into: geometric edges with the calibration, or
        today's clock edges when it was refused."""
        if cal.ok:
            return self._new_core(cal.ground_m, cal.offset_s, cal.pitch_offset_deg)
        return self._new_core(None, self._p.mocap_offset, self._p.pitch_offset)

    def _take_calibration(self) -> None:
        """The hand-over (this node's thread): once the worker is done, the calibrated core
        replaces the waiting one, the calibration is logged once, and the buffered stances'
        fits are published, before any later message is taken."""
        cal = self.calibration
        if cal is None or cal.state != 'ready':
            return
        got = cal.take()
        if got is None:
            return
        core, result, fits = got
        old = self.core
        if core.model.mass_kg != old.model.mass_kg:   # a run-time change meanwhile
            core.set_model(old.model)
        core.margin_s = old.margin_s
        self.core = core
        self._warnings_logged = self._notes_logged = self._skips_logged = 0
        log = self.get_logger()
        if result.ok:
            log.info(f'{result.line()}; worker {cal.replay_s:.2f} s with the replay of '
                     f'{cal.buffered} buffered messages ({cal.replayed_on_take} more taken '
                     'over here)')
            for w in result.warnings:
                log.warning(f'self-calibration: {w}')
        else:
            log.warning(f'{result.line()}: ' + clock_edges_warning(self._p))
        for err in cal.dropped:
            self.dropped += 1
            self._log_drop(f'dropped a buffered message: {err}')
        self._handed_over = len(fits)
        for r in fits:
            self.pub.publish(result_to_msg(r))
            self.published += 1
        self._log_core()

    def destroy_node(self) -> None:
        """Stop the self-calibration's worker (it stops at its next sample and no longer
        wakes the node) and publish the fits it had already computed, when it can (not once
        a stop signal has shut the context down: then how many were lost is logged)."""
        cal = self.calibration
        why = cal.pending() if cal is not None else ''
        if why and why != self._pending_said:
            self.get_logger().warning(why)
        if cal is not None and cal.close():
            before = self.published
            try:
                self._take_calibration()
            except Exception as err:   # noqa: BLE001 - the context is gone (a signal)
                lost = self._handed_over - (self.published - before)
                self.get_logger().warning(
                    f'{lost} self-calibrated fit(s) not published: the node stopped before '
                    f'they were handed over ({type(err).__name__})')
        super().destroy_node()

    def finish_offline(self, timeout_s: float | None = None) -> None:
        """Wait for a running self-calibration and hand it over (for
        :func:`hexapod_common.replay.run_offline`, which calls it after the bag: the
        buffered stances' fits are then published)."""
        cal = self.calibration
        why = cal.pending() if cal is not None else ''
        if why:
            if why != self._pending_said:   # said once (destroy_node would say it again)
                self.get_logger().warning(why)
                self._pending_said = why
        elif cal is not None and cal.wait(timeout_s):
            self._take_calibration()

    def _log_core(self) -> None:
        """The core's new warnings (once each), input notes and skipped stances."""
        warnings = self.core.warnings
        while self._warnings_logged < len(warnings):   # time jumps: once each
            self.get_logger().warning(warnings[self._warnings_logged])
            self._warnings_logged += 1
        notes = self.core.notes
        while self._notes_logged < len(notes):  # each input fallback logged once
            self.get_logger().info(notes[self._notes_logged])
            self._notes_logged += 1
        self._log_skips()

    def _calibrating(self, kind: str, *args: Any) -> bool:
        """Whether the self-calibration took the sample (it is buffering, or working)."""
        self._take_calibration()
        cal = self.calibration
        if cal is None or not cal.offer(kind, *args):
            return False
        while self._calibration_warned < len(cal.warnings):   # time jumps: once each
            self.get_logger().warning(cal.warnings[self._calibration_warned])
            self._calibration_warned += 1
        return True

    def _check_hips(self, names: Any) -> None:
        """Warn once when :data:`HIPLESS_MESSAGES` leg joint states came and none named a
        ``<leg>_hip`` joint: the stance detection needs the hips' angles, so nothing will be
        fitted (a 3-DOF hexapod's ``L1_coxa/femur/tibia`` gave no fit and no word why: an
        outside live review)."""
        if self._hipless is None:
            return
        if any(str(n).endswith('_hip') for n in names):
            self._hipless = None
            return
        self._hipless += 1
        if len(self._joint_names) < 64:
            self._joint_names.update(str(n) for n in names)
        if self._hipless == HIPLESS_MESSAGES:
            shown = sorted(self._joint_names)
            self.get_logger().warning(
                f'joint_states: no <leg>_hip joint in {HIPLESS_MESSAGES} messages (joints '
                f'{", ".join(shown[:6])}{" ..." if len(shown) > 6 else ""}): nothing can be '
                'fitted. slip_fitter is for RHex-class robots, one rotating hip per leg named '
                'L1_hip ... R3_hip, whose angles give the stances (-p ground) or the Buehler '
                'clock; a stepping robot\'s coxa/femur/tibia joints give neither')

    def _on_change(self, new: SlipParams) -> str | None:
        """Apply a run-time change of ``mass`` or ``margin`` (the others are read only)."""
        core = getattr(self, 'core', None)   # None while the node is being built
        if core is not None:
            if new.mass != core.model.mass_kg:
                core.set_model(SlipModel.from_name(new.model, mass_kg=new.mass))
            core.margin_s = new.margin
        return None

    def _guard(self, fn: Any, msg: Any, topic: str) -> None:
        self.received += 1
        try:
            fn(msg)
        except (ValueError, RuntimeError) as err:  # a bad message is logged and dropped
            self.dropped += 1
            self._log_drop(f'dropped a {topic} message: {err}')
        warnings = self.core.warnings
        while self._warnings_logged < len(warnings):   # time jumps: once each
            self.get_logger().warning(warnings[self._warnings_logged])
            self._warnings_logged += 1

    def _log_drop(self, text: str) -> None:
        """Log a dropped message: each distinct reason on its 1st, 10th, 100th, 1000th ...
        occurrence (another publisher on the topic, e.g. a gripper's joint_states at 10 Hz,
        would otherwise give one warning per message)."""
        key = text[:160] if len(self._drops) < MAX_DROP_REASONS or text[:160] in self._drops \
            else 'other reasons'
        n = self._drops[key] = self._drops.get(key, 0) + 1
        if n == 1 or n in (10, 100, 1000) or n % 10000 == 0:
            self.get_logger().warning(text if n == 1 else f'{text} [{n} such messages so far]')

    def _on_js(self, msg: JointState) -> None:
        self.inputs.seen('joint_states')
        self._guard(self._joint_state, msg, 'joint_states')

    def _signed(self, s: Any) -> Any:
        """A JointStateSample with the mirrored hips' values negated (``hip_signs``)."""
        if not self._hip_sign:
            return s
        k = np.array([self._hip_sign.get(n, 1.0) for n in s.names])
        return dataclasses.replace(s, **{f: getattr(s, f) * k if getattr(s, f).size == k.size
                                         else getattr(s, f)
                                         for f in ('position', 'velocity', 'effort')})

    def _count_loss(self, topic: str, group: Any, t_s: float) -> None:
        if t_s != 0.0:
            note = self.loss.observe_topic(topic, group, t_s)
            if note:
                self.get_logger().warning(note)

    def _check_clock(self, topic: str, t_s: float) -> None:
        """Report (once) a topic stamped on another clock than the others (a mocap bridge
        passing the capture system's time): the stream offset search cannot bridge it."""
        for err in self._clocks.observe(topic, t_s, self.get_clock().now().nanoseconds * 1e-9):
            self.get_logger().error(err)

    def _unrepeated(self, topic: str, group: Any, s: Any) -> Any:
        """``s``, re-stamped when it repeats its stream's previous stamp with new values;
        None when it cannot be placed (dropped). Logged on the 1st, 10th, 100th ..."""
        t = self._repeats.stamp(topic, group, s, self.get_clock().now().nanoseconds * 1e-9)
        if t == s.t_s:
            return s
        done = 're-stamped from their arrival times' if t is not None else \
            'dropped (arrival times too irregular to place them, or too few yet)'
        self._log_drop(repeat_note(1, topic, done).replace('1 ', '', 1).replace(
            'message(s)', 'messages'))
        return None if t is None else dataclasses.replace(s, t_s=t)

    def _legs_only(self, topic: str, sample: Any) -> Any:
        """``sample`` without joints that are not a leg's (a gripper beside the legs), as
        offline; None when it names none (a gripper's message before the legs' had become
        the core's joint set, every leg message refused after it). Logged once per new
        name."""
        # the SLIP analysis needs contract hips (L1_hip ...): other joints never help it
        f = self._leg_joints.setdefault(topic, LegJointFilter(legs_present=True))
        before = len(f.dropped)
        out = f.apply(sample)
        if len(f.dropped) > before:
            self.get_logger().warning(f'{topic}: ' + f.note('the stance detection and fits'))
        return out

    def _joint_state(self, msg: JointState) -> None:
        s = self._legs_only('joint_states', self._signed(joint_state_from_msg(msg)))
        if s is None:
            return
        self._check_hips(s.names)
        if s.t_s != 0.0:
            s = self._unrepeated('joint_states', tuple(s.names), s)
            if s is None:
                return
        self._check_clock('joint_states', s.t_s)
        self._count_loss('joint_states', tuple(s.names), s.t_s)
        if self._calibrating('js', s):
            return
        self.core.add_joint_state(s.t_s, s.names, s.velocity, s.position)
        notes = self.core.notes
        while self._notes_logged < len(notes):  # each input fallback logged once
            self.get_logger().info(notes[self._notes_logged])
            self._notes_logged += 1

    def _on_cmd(self, msg: JointState) -> None:
        self._guard(self._command, msg, 'joint_commands')

    def _command(self, msg: JointState) -> None:
        s = self._legs_only('joint_commands', self._signed(joint_state_from_msg(msg)))
        if s is not None and not self._calibrating('cmd', s):
            self.core.add_command(s.t_s, s.names, s.velocity)

    def _on_mocap(self, msg: PoseStamped) -> None:
        self.inputs.seen('mocap/body')
        self._guard(self._mocap_and_fit, msg, 'mocap/body')

    def _mocap_and_fit(self, msg: PoseStamped) -> None:
        s = pose_from_msg(msg)
        if s.t_s != 0.0:
            s = self._unrepeated('mocap/body', None, s)
            if s is None:
                return
        self._check_clock('mocap/body', s.t_s)
        self._count_loss('mocap/body', None, s.t_s)
        q = s.orientation_xyzw if self._body_up == 'z' else \
            rotate_body(s.orientation_xyzw, self._body_up)[0]
        if self._calibrating('mocap', s.t_s, s.position_m, q):
            return
        self.core.add_mocap(s.t_s, s.position_m, q)
        for r in self.core.step():
            self.pub.publish(result_to_msg(r))
            self.published += 1
        self._log_skips()

    def _log_skips(self) -> None:
        """Stances not fitted, by reason: each reason logged on its 1st, 10th, 100th ...
        stance (info for ``frame_not_ready``, the first stances of a run; warnings else).
        They had not been reported at all."""
        skipped = self.core.skipped
        while self._skips_logged < len(skipped):
            sk = skipped[self._skips_logged]
            self._skips_logged += 1
            n = self.skipped_counts[sk.reason] = self.skipped_counts.get(sk.reason, 0) + 1
            if not (n == 1 or n in (10, 100, 1000) or n % 10000 == 0):
                continue
            why = SKIP_REASONS.get(sk.reason, sk.reason)
            who = f'{sk.tripod} stance' if sk.tripod else 'stances in'
            text = (f'{who} {sk.touchdown_s:.3f}-{sk.liftoff_s:.3f} s not fitted: '
                    f'{why} [{n} stance(s) so far for this reason]')
            # two call sites: rclpy refuses a second severity from one (a ValueError that
            # stopped the node when a frame_not_ready skip and another reason were logged,
            # e.g. together at the self-calibration's hand-over; an outside review)
            if sk.reason == 'frame_not_ready':
                self.get_logger().info(text)
            else:
                self.get_logger().warning(text)


def main(args: list[str] | None = None) -> int:
    """Console script ``slip_fitter``."""
    return run_node(SlipFitterNode, args)
