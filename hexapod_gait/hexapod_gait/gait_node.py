"""``gait_scheduler``: publishes the gait schedule and the joint commands that walk it.

Publishes ``gait/phase`` (hexapod_interfaces/GaitPhase) and ``joint_commands``
(sensor_msgs/JointState, position and velocity) at ``rate`` Hz on a timer of the node clock
(so ``use_sim_time`` works); their ``header.frame_id`` is ``<node>@<pid>@<ns>``: the node's
fully qualified name, its process and the wall time of its first command (who sent the
schedule, and since when). Parameter changes at run time start a phase-continuous transition
(:class:`hexapod_gait.scheduler.GaitScheduler`); an infeasible request is refused with its reason
and the gait keeps running. The science is in the core modules of :mod:`hexapod_gait`.

Live-robot rules on top of the core's feasibility and reach: a gait that lifts every leg of one
side at once (the wave at duty factor 0.5) is refused (:func:`hexapod_gait.config.
check_static_support`), and so is a change whose transition would lift a side on the way
when no staged transition avoids it (:meth:`~hexapod_gait.scheduler.GaitScheduler.set_gait`);
``transition_cycles`` is at least
:data:`~hexapod_gait.scheduler.MIN_TRANSITION_CYCLES`; ``period`` cannot change while
``speed > 0`` (the speed chooses it). A multi-parameter change is checked as one set when sent
in one ``set_parameters_atomically`` call (``ros2 param set`` sends one parameter at a time).

Stand / stop: ``ros2 param set /gait_scheduler stand true`` (or ``step_length`` and
``step_height`` 0) moves every tip to its neutral stance over one transition and holds it;
``gait/phase`` then shows every leg in stance. ``stand false`` walks again.

Ctrl-C / SIGTERM (console script): the legs are stood first (``stand``, one transition), and
the node exits (code 0) once ``gait/phase`` shows the stand settled; if the stand is refused or
has not settled after ``stop_timeout_s``, it exits with :data:`EXIT_NOT_STOOD` (1), the legs
where they are; a second signal exits at once (code 1). (Before, the commands stopped wherever
the legs were: a bench leg froze 35 mm above the ground, and the sequencer later cut its torque
there.) A Buehler clock has no stand: its node exits at once.

One gait node per robot: the node listens to its own topics (``gait/phase``,
``joint_commands``). It sends its first command ``startup_listen_s`` (0.5 s) after its first
tick, time for discovery; when the graph then lists another publisher there, it listens
:data:`STARTUP_LISTEN_S` more for that publisher's messages (a crashed node's endpoint
stays in the graph until its DDS lease runs out, and sends nothing). A message from another
publisher before its first command makes it refuse to walk: it publishes nothing more and
exits with :data:`EXIT_ANOTHER_GAIT` (2). After its first command, another publisher is told
from the messages' publication sequence numbers (:mod:`hexapod_common.publishers`; a
middleware without them leaves only the check before the first command); which node
walked first is told from each publisher's start: the one another gait node states in its
frame_id, else extrapolated from its numbers and send times. The one that started more than
:data:`NEWCOMER_MARGIN_S` earlier keeps walking and logs an error (once per episode) naming
the publishers, the other stops; two that started within that of each other both stop. (Before, two ``gait_scheduler`` or a
lab's own command node interleaved their commands without a word.)
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('gait_scheduler')

import collections
import functools
import math
import os
import re
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from hexapod_interfaces.msg import GaitPhase
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.task import Future
from sensor_msgs.msg import JointState

from hexapod_common.conversions import s_to_stamp
from hexapod_common.errors import ParameterError
from hexapod_common.node_utils import (
    RELIABLE_QOS,
    SENSOR_QOS,
    declare_params,
    on_stop_signals,
    overridden,
    param,
    publisher_names,
    run_node,
)
from hexapod_common.publishers import (
    PublisherSequences,
    publication_sequence,
    source_time,
)
from hexapod_gait.buehler import BUEHLER_PRESETS, BuehlerClock
from hexapod_gait.config import build_gait, check_static_support
from hexapod_gait.errors import HexapodGaitError
from hexapod_gait.feasibility import ActuatorLimits, period_for_speed
from hexapod_gait.leg_file import LegFile, LegFileError, read_leg_file
from hexapod_gait.gait import GAIT_NAMES, GaitPattern
from hexapod_gait.scheduler import MIN_TRANSITION_CYCLES, GaitScheduler, GaitState
from hexapod_gait.step_limits import limits_for_step, measured_on_leg

__all__ = ['EXIT_ANOTHER_GAIT', 'EXIT_NOT_STOOD', 'NEWCOMER_MARGIN_S', 'STARTUP_LISTEN_S', 'GaitParams',
           'GaitSchedulerNode', 'gait_state_to_msg',
           'joint_command_msg', 'main', 'stand_on_signals']

#: Exit code of a stop (Ctrl-C / SIGTERM) that could not stand the legs (the stand was refused,
#: or did not settle within ``stop_timeout_s``): the legs are left where they are.
EXIT_NOT_STOOD = 1
#: Exit code of a node that found another publisher on its topics that walked first, or
#: started with it (two schedules would drive one robot's joints)
EXIT_ANOTHER_GAIT = 2
#: a node that hears another publisher on its topics stops unless it started more than this
#: many seconds before the other (the other walked first, or both started together; the same
#: margin on both sides, whatever their rates)
NEWCOMER_MARGIN_S = 0.02
#: without sequence numbers (a middleware that gives none): a node that hears another
#: publisher within this many seconds of its first command stops
NEWCOMER_S = 2.0
#: another publisher silent this long [s] (and 3 times its longest gap so far) and heard again
#: starts a new episode (judged and reported again)
FOREIGN_QUIET_S = 10.0

#: ``header.frame_id`` of this node's messages: ``<node>@<pid>@<first command, ns of wall
#: time>`` (who sent it, and since when: :func:`_stated_start`)
_FRAME_RE = re.compile(r'@(\d+)@(\d+)$')


def _stated_start(data: bytes, kind: Any) -> float | None:
    """The wall time [s] another gait node says it sent its first command (its frame_id),
    None for a publisher that does not say (not a gait_scheduler, or an older one)."""
    try:
        frame = deserialize_message(bytes(data), kind).header.frame_id
    except Exception:   # noqa: BLE001 - bytes of another type or version: it does not say
        return None
    m = _FRAME_RE.search(str(frame))
    return int(m.group(2)) * 1e-9 if m else None


class _SentHashes:
    """The hashes of the last messages a node sent on a topic (a bounded multiset)."""

    def __init__(self, size: int = 512) -> None:
        self._order: collections.deque[int] = collections.deque()
        self._count: dict[int, int] = {}
        self.size = size

    def add(self, h: int) -> None:
        self._order.append(h)
        self._count[h] = self._count.get(h, 0) + 1
        if len(self._order) > self.size:
            old = self._order.popleft()
            self._count[old] -= 1
            if not self._count[old]:
                del self._count[old]

    def __contains__(self, h: int) -> bool:
        return h in self._count
#: before its first command, a node whose topics have another publisher in the graph listens
#: this long [s] for that publisher's messages (none: a crashed node's endpoint)
STARTUP_LISTEN_S = 1.0


def _positive(v: float) -> str | None:
    return None if v > 0 else 'must be > 0'


@dataclass(frozen=True)
class GaitParams:
    gait: str = param(
        'tripod', 'tripod, alternating, wave, ripple, tetrapod or buehler (1 hip per leg)',
        validate=lambda v: None if v in GAIT_NAMES and v != 'custom'
        else f'expected one of {[g for g in GAIT_NAMES if g != "custom"]}')
    leg_count: int = param(6, 'number of legs (even, >= 2); cannot change while walking',
                           validate=lambda v: None if v >= 2 and v % 2 == 0
                           else 'must be even and >= 2')
    duty_factor: float = param(0.5, 'beta = T_stance / T (Buehler: duty cycle dc)',
                               validate=lambda v: None if 0 < v < 1 else 'must be in (0, 1)')
    period: float = param(1.0, 'cycle period T [s] (ignored when speed > 0)', validate=_positive)
    step_length: float = param(0.10, 'distance travelled in one stance [m]',
                               validate=lambda v: None if v >= 0 else 'must be >= 0')
    step_height: float = param(0.04, 'swing lift [m]',
                               validate=lambda v: None if v >= 0 else 'must be >= 0')
    speed: float = param(0.0, 'body speed [m/s]; > 0 chooses the period, 0 uses period',
                         validate=lambda v: None if v >= 0 else 'must be >= 0')
    rate: float = param(100.0, 'command rate [Hz]', validate=_positive, read_only=True)
    sweep_angle: float = param(1.0, 'Buehler clock sweep angle phi_s [rad]',
                               validate=lambda v: None if 0 < v < 6.283185307179586
                               else 'must be in (0, 2 pi)')
    leg_offset: float = param(0.0, 'Buehler clock leg offset phi_0 [rad]')
    preset: str = param('', 'Buehler preset (running, jogging, pace, walk); empty = parameters',
                        validate=lambda v: None if v in ('', *BUEHLER_PRESETS)
                        else f'expected one of {sorted(BUEHLER_PRESETS)} or empty')
    transition_cycles: float = param(
        1.0, f'duration of a transition in gait periods (>= {MIN_TRANSITION_CYCLES:g})',
        validate=lambda v: None if v >= MIN_TRANSITION_CYCLES
        else f'must be >= {MIN_TRANSITION_CYCLES:g} (faster changes jump the joints)')
    stand: bool = param(False, 'true: stand (every tip at its neutral stance, step 0) and hold; '
                        'false: walk the gait parameters')
    stop_timeout_s: float = param(5.0, 'Ctrl-C / SIGTERM: longest wait for the stand before '
                                  'the node exits [s] (exit code 1 if the legs did not stand)',
                                  validate=_positive)
    startup_listen_s: float = param(
        0.5, 'before the first command, listen this long [s] for another gait node on '
        'gait/phase and joint_commands (discovery takes tens of ms; 0: walk at the first tick)',
        validate=lambda v: None if 0 <= v <= 10 else 'must be in [0, 10]', read_only=True)
    min_swing: float = param(0.16, 'actuator limit: shortest swing [s] on the 100 mm, 40 mm '
                             "bench step (scaled by the joint path of other steps); AntBot's "
                             "AX-18A on AntBot's leg, or given with leg_file: on that leg",
                             validate=_positive, read_only=True)
    min_stance: float = param(0.15, 'actuator limit: shortest stance [s] on the 100 mm, 40 mm '
                              "bench step (scaled by the joint path of other steps); AntBot's "
                              "AX-18A on AntBot's leg, or given with leg_file: on that leg",
                              validate=_positive, read_only=True)
    max_step_frequency: float = param(3.0, 'actuator limit: highest step frequency [Hz]',
                                      validate=_positive, read_only=True)
    leg_file: str = param('', "the robot's leg (YAML/JSON: DH table, link masses, "
                          "neutral_tip_m; hexapod_gait.leg_file); empty = AntBot's",
                          read_only=True)


def _limits(p: GaitParams, measured_on: LegFile | None = None) -> ActuatorLimits:
    """The actuator limits of the parameters, measured on ``measured_on``'s 100 mm, 40 mm
    bench step (None: AntBot's leg, where the default AX-18A limits were measured)."""
    lim = ActuatorLimits(min_swing_s=p.min_swing, min_stance_s=p.min_stance,
                         max_step_frequency_hz=p.max_step_frequency)
    return lim if measured_on is None else measured_on_leg(lim, measured_on)


def gait_from_params(p: GaitParams, leg: LegFile | None = None, *,
                     limits_on_leg: bool = False) -> GaitPattern | BuehlerClock:
    """The gait the parameters describe (raises a :class:`HexapodGaitError` with the reason).

    Standing (``stand``, or step length and height 0) keeps the walking gait's cycle clock: the
    period the speed chooses when ``speed > 0`` and the walking gait reaches it, else
    ``period``; so standing changes only the step, not the timing. A stand does not move, so
    it is not checked against the actuator timing limits (the walking 8-leg wave at beta 0.875
    could not stand: its stand was checked at ``period`` 1 s, a 0.125 s swing). A walking
    3-DOF gait must keep a leg on the ground on each side (:func:`check_static_support`).
    The actuator limits are the bench step's, scaled to this step's joint path
    (:mod:`hexapod_gait.step_limits`): a 140 mm step needs swing >= 0.192 s, stance >= 0.221 s.
    They were measured on AntBot's leg, or with ``limits_on_leg`` (``min_swing`` or
    ``min_stance`` given with ``leg_file``) on ``leg``: another leg walks its own joint path
    against that leg's bench path (a PhantomX-like leg at 100 mm, AntBot's limits: swing >=
    0.185 s, stance >= 0.168 s).
    """
    standing = p.gait != 'buehler' and (p.stand or (p.step_length == 0.0
                                                     and p.step_height == 0.0))
    # the leg's joint paths (another robot's leg file): its reach and actuator limits
    on_leg: dict[str, Any] = {} if leg is None else {
        'kinematics': leg.kinematics(), 'neutral_tip_m': leg.neutral_tip_m}
    limits = _limits(p, leg if limits_on_leg else None)
    period = p.period
    if standing and p.speed > 0.0 and p.step_length > 0.0:
        try:
            period = period_for_speed(p.speed, p.duty_factor, p.step_length, limits_for_step(
                limits, p.duty_factor, p.step_length, p.step_height, **on_leg))
        except HexapodGaitError:
            pass    # the walking gait is not reachable: the stand keeps ``period``
    gait = build_gait(p.gait, leg_count=p.leg_count, duty_factor=p.duty_factor,
                      period_s=period, step_length_m=0.0 if standing else p.step_length,
                      step_height_m=0.0 if standing else p.step_height,
                      speed_mps=0.0 if standing else p.speed,
                      sweep_angle_rad=p.sweep_angle, leg_offset_rad=p.leg_offset,
                      preset=p.preset, limits=None if standing else limits, **on_leg)
    if isinstance(gait, GaitPattern):
        check_static_support(gait)
    return gait


def _stamp(msg: Any, t_ns: int | None, t_s: float) -> None:
    if t_ns is not None:
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(t_ns), 1_000_000_000)
    else:
        msg.header.stamp.sec, msg.header.stamp.nanosec = s_to_stamp(t_s)


def gait_state_to_msg(state: GaitState, t_s: float, msg: Any = None, *,
                      t_ns: int | None = None) -> GaitPhase:
    """Fill a GaitPhase message from a scheduler state.

    The stamp is ``t_ns`` [ns] when given (exact), else ``t_s`` rounded to the nanosecond.
    """
    msg = msg or GaitPhase()
    _stamp(msg, t_ns, t_s)
    g = state.gait
    msg.gait = g.name
    msg.period = g.period_s
    msg.duty_factor = g.duty_factor
    msg.step_length = g.step_length_m
    msg.step_height = g.step_height_m
    msg.sweep_angle = state.clock.sweep_angle_rad if state.clock is not None else 0.0
    msg.leg_offset = state.clock.leg_offset_rad if state.clock is not None else 0.0
    msg.cycle_phase = state.cycle_phase
    msg.leg_names = list(g.leg_names)
    msg.phase_offsets = [float(x) for x in g.phase_offsets]
    msg.in_stance = [bool(x) for x in state.in_stance]
    msg.supporting_legs = int(state.supporting_legs)
    return msg


def joint_command_msg(t_s: float, names: Sequence[str], q: Sequence[float],
                      qd: Sequence[float], *, t_ns: int | None = None) -> JointState:
    """A JointState command with position and velocity (stamp as in :func:`gait_state_to_msg`)."""
    msg = JointState()
    _stamp(msg, t_ns, t_s)
    msg.name = list(names)
    msg.position = [float(x) for x in q]
    msg.velocity = [float(x) for x in qd]
    return msg


class GaitSchedulerNode(Node):
    """Thin node around :class:`GaitScheduler`."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, node_name: str = 'gait_scheduler',
                 **kw: Any) -> None:
        super().__init__(node_name, context=context, namespace=namespace or '',
                         parameter_overrides=parameter_overrides or [], **kw)
        self.scheduler: GaitScheduler | None = None
        # The scheduler runs on seconds since the first tick, t0_ns: wall-clock seconds as one
        # float resolve only about 0.2 us.
        self.t0_ns: int | None = None
        self.t0_s: float | None = None
        p = declare_params(self, GaitParams, on_change=self._on_change)
        # added last, so rclpy runs it before the change is applied
        self.add_on_set_parameters_callback(self._refuse_period_in_speed_mode)
        #: the robot's leg (leg_file), None for AntBot's: the joint commands' inverse
        #: kinematics, the stand pose and the reach checks (they were AntBot's on any robot)
        self.leg: LegFile | None = None
        if p.leg_file:
            try:
                self.leg = read_leg_file(p.leg_file)
            except LegFileError as err:
                raise ParameterError(f'leg_file refused: {err}') from err
            self.get_logger().info(f'leg {self.leg.name!r} from {p.leg_file}: link lengths '
                                   f'{[round(x, 4) for x in self.leg.dh.a_m]} m, neutral tip '
                                   f'{[round(x, 4) for x in self.leg.neutral_tip_m]} m')
        #: the actuator limits were measured on the leg file's leg (min_swing or min_stance
        #: given with leg_file), else on AntBot's (the AX-18A defaults): another leg's step is
        #: scaled against that leg's 100 mm bench path (it was against its own)
        self.limits_on_leg = self.leg is not None and (
            overridden(self, 'min_swing') or overridden(self, 'min_stance'))
        if self.leg is not None:
            whose = (f'given: measured on {self.leg.name!r}' if self.limits_on_leg else
                     "AntBot's AX-18A, measured on AntBot's leg (give min_swing and "
                     'min_stance measured on this leg otherwise)')
            self.get_logger().info(
                f'actuator limits swing >= {p.min_swing:g} s, stance >= {p.min_stance:g} s on '
                f'the 100 mm, 40 mm bench step ({whose}); each step is scaled by its joint '
                f'path on {self.leg.name!r}')
        try:
            self._gait = gait_from_params(p, self.leg, limits_on_leg=self.limits_on_leg)
        except HexapodGaitError as err:
            raise ParameterError(f'gait parameters refused: {err}') from err
        self.phase_pub = self.create_publisher(GaitPhase, 'gait/phase', RELIABLE_QOS)
        self.cmd_pub = self.create_publisher(JointState, 'joint_commands', RELIABLE_QOS)
        self.ticks = 0
        #: resolved once a requested stop has stood the legs (request_stop): exit code 0;
        #: EXIT_NOT_STOOD if the stand was refused or did not settle within stop_timeout_s
        self.finished = Future()
        self._stop_reason: str | None = None   # a stop requested (signal), not yet begun
        self._stop_began_s: float | None = None
        self._stop_requests = 0
        # one gait node per robot: its own topics, listened to (module docs)
        self._own_pubs = {'gait/phase': self.phase_pub, 'joint_commands': self.cmd_pub}
        # hashes of the messages this node sent (its own, when they come back), and the other
        # publishers' numbers and send times
        self._sent = {topic: _SentHashes() for topic in self._own_pubs}
        self._foreign = {topic: PublisherSequences() for topic in self._own_pubs}
        self._foreign_last: dict[str, float] = {}
        self._foreign_gap: dict[str, float] = {}
        self._own_types = {'gait/phase': GaitPhase, 'joint_commands': JointState}
        self._foreign_decided: set[str] = set()
        self._first_command_wall = math.nan
        for topic, kind in (('gait/phase', GaitPhase), ('joint_commands', JointState)):
            self.create_subscription(kind, topic, functools.partial(self._on_own_topic, topic),
                                     SENSOR_QOS, raw=True)
        self._foreign_before_start: str | None = None
        self._listen_until_ns: int | None = None
        self._listen_extended = False
        self._first_command_ns: int | None = None
        #: episodes of another publisher on gait/phase or joint_commands, reported
        self.other_publishers_reported = 0
        self.timer = self.create_timer(1.0 / p.rate, self._on_timer)
        self.get_logger().info(f'walking {self._describe(self._gait)}')

    @staticmethod
    def _describe(g: GaitPattern | BuehlerClock) -> str:
        if isinstance(g, BuehlerClock):
            return (f'buehler clock T={g.period_s:.4g} s dc={g.duty_factor:.3g} '
                    f'sweep={g.sweep_angle_rad:.3g} rad offset={g.leg_offset_rad:.3g} rad')
        return (f'{g.name} on {g.leg_count} legs, beta={g.duty_factor:.3g}, '
                f'T={g.period_s:.4g} s, step {g.step_length_m:.3g} m, v={g.speed_mps:.3g} m/s')

    def _now_s(self) -> float:
        """Scheduler time: seconds since the first tick (0 before it)."""
        now_ns = self.get_clock().now().nanoseconds
        return 0.0 if self.t0_ns is None else (now_ns - self.t0_ns) * 1e-9

    def _refuse_period_in_speed_mode(self, parameters: list[Any]) -> SetParametersResult:
        """Setting ``period`` while ``speed > 0`` is refused: it would be accepted and ignored
        (the speed chooses the period), so a caller would believe it walks that period."""
        names = {p.name: p.value for p in parameters}
        speed = names.get('speed', self.params.speed)
        if 'period' in names and speed > 0:
            reason = (f'period {names["period"]} s is ignored while speed = {speed:g} m/s > 0 '
                      '(the speed chooses the period); set speed 0 to walk a period')
            self.get_logger().warning(f'gait change refused: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _on_change(self, new: GaitParams) -> str | None:
        """Validate a run-time change and start a transition; a returned string refuses it."""
        try:
            gait = gait_from_params(new, self.leg, limits_on_leg=self.limits_on_leg)
            if self.scheduler is not None:
                cycles = self.scheduler.transition_cycles
                self.scheduler.transition_cycles = new.transition_cycles
                try:
                    self.scheduler.set_gait(gait, max(self._now_s(),
                                                      self.scheduler.last_change_s))
                except HexapodGaitError:
                    self.scheduler.transition_cycles = cycles   # refused: nothing changes
                    raise
        except HexapodGaitError as err:
            self.get_logger().warning(f'gait change refused: {err}')
            return str(err)
        self._gait = gait
        self.get_logger().info(f'transition to {self._describe(gait)}')
        return None

    def request_stop(self, reason: str) -> None:
        """Stand the legs, then exit (:attr:`finished`); a second request exits at once.
        Safe from a signal handler: the stand starts on the next timer tick."""
        self._stop_requests += 1
        if self._stop_requests > 1:
            self.get_logger().warning(f'{reason} again: exiting with the legs where they are '
                                      f'(exit code {EXIT_NOT_STOOD})')
            if not self.finished.done():
                # the legs not stood: exit 1, as a stand refused or timed out (it was 0)
                self.finished.set_result(EXIT_NOT_STOOD)
            return
        self._stop_reason = reason

    def _begin_stop(self, reason: str, now_s: float) -> None:
        self._stop_began_s = now_s
        if self.scheduler is None or isinstance(self._gait, BuehlerClock):
            why = 'a Buehler clock has no stand' if self.scheduler else 'not started'
            self.get_logger().info(f'{reason}: exiting ({why})')
            self.finished.set_result(0)
            return
        if not self.params.stand:
            result = self.set_parameters([Parameter('stand', value=True)])[0]
            if not result.successful:
                self.get_logger().error(
                    f'{reason}: the stand was refused ({result.reason}): exiting with the legs '
                    f'where they are (exit code {EXIT_NOT_STOOD})')
                self.finished.set_result(EXIT_NOT_STOOD)
                return
        self.get_logger().warning(
            f'{reason}: standing the legs before exiting (at most {self.params.stop_timeout_s:g}'
            ' s; again to exit at once)')

    def _check_stop(self, state: GaitState, now_s: float) -> None:
        """Resolve :attr:`finished` once the stand has settled (the state carries the target
        gait, step 0, only once the transition is over), or at ``stop_timeout_s``."""
        assert self._stop_began_s is not None
        g = state.gait
        if g.step_length_m == 0.0 and g.step_height_m == 0.0:
            self.get_logger().info('legs stood: exiting')
            self.finished.set_result(0)
        elif now_s - self._stop_began_s > self.params.stop_timeout_s:
            self.get_logger().error(
                f'the legs did not stand within stop_timeout_s = '
                f'{self.params.stop_timeout_s:g} s: exiting with them where they are '
                f'(exit code {EXIT_NOT_STOOD})')
            self.finished.set_result(EXIT_NOT_STOOD)

    def _publisher_names(self, topic: str) -> str:
        """The graph's publishers of one of this node's topics, for a message."""
        return publisher_names(self, self._own_pubs[topic].topic_name)

    def _on_own_topic(self, topic: str, data: Any, info: Any) -> None:
        """A message on one of this node's own topics: its own (the very bytes it sent), or
        another publisher's."""
        if self.finished.done():
            return
        if self._first_command_ns is None:   # nothing sent yet: another publisher's
            if self._foreign_before_start is None:
                self._foreign_before_start = topic
            return
        if hash(bytes(data)) in self._sent[topic]:
            return                            # our own
        foreign = self._foreign[topic]
        seq = publication_sequence(info)
        foreign.add(seq, source_time(info))
        now = time.time()
        gap = now - self._foreign_last.get(topic, -math.inf)
        self._foreign_last[topic] = now
        longest = self._foreign_gap.get(topic, 0.0)
        if gap > max(FOREIGN_QUIET_S, 3.0 * longest):
            self._foreign_decided.discard(topic)   # a new episode
            self._foreign_gap[topic] = 0.0
        else:
            self._foreign_gap[topic] = max(longest, gap)
        if topic in self._foreign_decided:
            return
        # who walked first. Another gait node says when it started (its frame_id): both then
        # judge the same two numbers (a review: starts extrapolated from the numbers moved a
        # node paused by SIGSTOP later, and both kept walking). Else the other's start is
        # extrapolated from its numbers and send times (counts alone misjudged nodes of
        # different rates: a 10 Hz node walking 4 s stopped for a 100 Hz newcomer)
        stated = _stated_start(data, self._own_types[topic])
        starts = [x for x in foreign.series_starts() if x is not None]
        if stated is None and seq is not None and not starts and foreign.messages < 3:
            return                            # one message: its rate not known yet
        own_start = self._first_command_wall
        other_start = stated if stated is not None else (min(starts) if starts else None)
        margin = NEWCOMER_MARGIN_S
        walked_s = now - own_start
        if other_start is None:               # a middleware without numbers: the time rule
            newcomer, tie = walked_s < NEWCOMER_S, False
        else:
            newcomer = own_start >= other_start - margin
            tie = abs(own_start - other_start) <= margin
        self._foreign_decided.add(topic)
        name = self._own_pubs[topic].topic_name
        if newcomer:
            when = ('' if other_start is None else
                    f'; it started {own_start - other_start:.3f} s before this node')
            self.get_logger().error(
                f'another node publishes on {name} (publishers in the graph: '
                f'{self._publisher_names(topic)}{when}): two schedules would drive the same '
                f'joints; this node stops publishing and exits (code {EXIT_ANOTHER_GAIT}), '
                + ('both started within a few commands of each other, so both stop' if tie
                   else 'the other, walking longer, keeps the robot'))
            self.finished.set_result(EXIT_ANOTHER_GAIT)
            return
        self.other_publishers_reported += 1
        self.get_logger().error(
            f'another node publishes on {name} (publishers in the graph: '
            f'{self._publisher_names(topic)}): its messages interleave with this node\'s and the '
            'joints follow two schedules; stop it (this node, walking for '
            f'{walked_s:.1f} s, keeps walking)')

    def _listen_before_start(self, now_ns: int) -> bool:
        """Before the first command: True while this node must not walk yet (another
        publisher in the graph, listened to for :data:`STARTUP_LISTEN_S`), and the refusal
        (``finished``) when that publisher spoke."""
        if self._foreign_before_start is not None:
            topic = self._foreign_before_start
            self.get_logger().error(
                f'another node already publishes on {self._own_pubs[topic].topic_name} '
                f'(publishers in the graph: {self._publisher_names(topic)}): two schedules would '
                'drive the same joints; refusing to walk (stop the other gait node first), '
                f'exit code {EXIT_ANOTHER_GAIT}')
            self.finished.set_result(EXIT_ANOTHER_GAIT)
            return True
        if self._listen_until_ns == 0:        # listened: walking
            return False
        if self._listen_until_ns is None:
            self._listen_until_ns = now_ns + int(self.params.startup_listen_s * 1e9)
        if now_ns < self._listen_until_ns:
            return True
        if not self._listen_extended:
            busy = [t for t, pub in self._own_pubs.items()
                    if self.count_publishers(pub.topic_name) > 1]
            if busy:
                self._listen_extended = True
                self._listen_until_ns = now_ns + int(STARTUP_LISTEN_S * 1e9)
                self.get_logger().warning(
                    f'the graph lists another publisher on '
                    f'{self._own_pubs[busy[0]].topic_name} ({self._publisher_names(busy[0])}): '
                    f'listening {STARTUP_LISTEN_S:g} s for its messages before walking')
                return True
        else:
            self.get_logger().info(
                f'nothing came from the other publisher in {STARTUP_LISTEN_S:g} s (a stopped '
                'node\'s endpoint, listed until its DDS lease runs out): walking')
        self._listen_until_ns = 0
        return False

    def _on_timer(self) -> None:
        now_ns = self.get_clock().now().nanoseconds
        if self.finished.done():
            return
        if self._stop_reason is not None and self._stop_began_s is None:
            self._begin_stop(self._stop_reason, now_ns * 1e-9)
            if self.finished.done():
                return
        if now_ns <= 0:
            return  # sim time not started
        if self.scheduler is None:
            if self._listen_before_start(now_ns):
                return
            self.t0_ns = now_ns
            self.t0_s = now_ns * 1e-9
            on_leg: dict[str, Any] = {} if self.leg is None else {
                'kinematics': self.leg.kinematics(), 'neutral_tip_m': self.leg.neutral_tip_m}
            self.scheduler = GaitScheduler(
                self._gait, 0.0, leg_count=self.params.leg_count,
                transition_cycles=self.params.transition_cycles, **on_leg)
        assert self.t0_ns is not None
        t = (now_ns - self.t0_ns) * 1e-9
        try:
            state = self.scheduler.state(t)
            names, q, qd = self.scheduler.joint_targets(t)
        except HexapodGaitError as err:
            self.get_logger().error(f'no command at t={t:.3f} s: {err}',
                                    throttle_duration_sec=5.0)
            return
        if self._first_command_ns is None:
            self._first_command_ns = now_ns
            wall_ns = time.time_ns()
            self._first_command_wall = wall_ns * 1e-9
            self._frame_id = f'{self.get_fully_qualified_name()}@{os.getpid()}@{wall_ns}'
        # sent as bytes, their hashes kept: this node knows its own messages when they come
        # back on its listening subscriptions
        for topic, msg in (('gait/phase', gait_state_to_msg(state, t, t_ns=now_ns)),
                           ('joint_commands', joint_command_msg(t, names, q, qd, t_ns=now_ns))):
            # who sent it (two gait nodes on one clock send the same schedule otherwise byte
            # for byte, and each would take the other's for its own)
            msg.header.frame_id = self._frame_id
            data = serialize_message(msg)
            self._sent[topic].add(hash(data))
            self._own_pubs[topic].publish(data)
        self.ticks += 1
        if self._stop_began_s is not None:
            self._check_stop(state, now_ns * 1e-9)


def stand_on_signals(node: GaitSchedulerNode,
                     signals: Sequence[int] = (signal.SIGINT, signal.SIGTERM)) -> None:
    """SIGINT / SIGTERM stand the legs before the node exits
    (:meth:`GaitSchedulerNode.request_stop`) instead of shutting rclpy down mid-step."""
    on_stop_signals(node.request_stop, signals, node=node,
                    wall_timeout_s=node.params.stop_timeout_s + 1.0)


def _node_standing_on_signals(**kw: Any) -> GaitSchedulerNode:
    """``gait_scheduler`` built by the console script (signals stand the legs first)."""
    node = GaitSchedulerNode(**kw)
    stand_on_signals(node)
    return node


def main(args: Sequence[str] | None = None) -> int:
    return run_node(_node_standing_on_signals, args, params=GaitParams)
