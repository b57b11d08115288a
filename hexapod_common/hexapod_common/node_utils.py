"""Conventions shared by every node: parameter schema, QoS profiles, the Jazzy ``main()``.

Parameters are declared from one frozen dataclass per node. Each field becomes a ROS parameter
whose type is the field's type, whose description comes from ``field(metadata={'description':
...})`` and whose optional validator (``metadata={'validate': callable}``) runs both at start-up
and on run-time changes, so a bad value is refused with its reason.

A float parameter (or every element of a float list) must be finite unless its field says
``finite=False`` (a NaN that means "off"): NaN compares false, so a NaN limit is never reached.

Run-time changes: a parameter is writable only when a run-time change takes effect. That is a
field declared ``live=True`` (the node reads ``node.params`` at every use), or any field not
``read_only`` of a node that passes ``on_change`` to :func:`declare_params` (the handler applies
the change). Every other parameter is read only, so ``ros2 param set`` is refused with a reason
instead of answering ``successful`` and changing nothing.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import os
import signal
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, TypeVar

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from hexapod_common.errors import ParameterError

__all__ = [
    'FirstPublisherWatch',
    'InputWatch',
    'LATCHED_QOS',
    'PublishersWatch',
    'RELIABLE_QOS',
    'SENSOR_QOS',
    'close_node',
    'declare_params',
    'find_params_class',
    'mocap_msg_class',
    'node_help',
    'on_stop_signals',
    'overridden',
    'param',
    'params_from_overrides',
    'publisher_names',
    'run_node',
    'stopping_errors',
    'validate_params',
    'wants_help',
    'writable_params',
]

T = TypeVar('T')


def on_stop_signals(stop: Callable[[str], None],
                    signals: Sequence[int] = (signal.SIGINT, signal.SIGTERM), *,
                    node: Any = None, wall_timeout_s: float = 10.0) -> None:
    """SIGINT / SIGTERM call ``stop('SIGINT received')`` instead of shutting rclpy down: a
    node that moves a leg stops it safely first (the bench sequencer, the gait scheduler) and
    resolves its ``finished`` future for :func:`run_node`.

    With ``node`` (which has ``finished``): a steady-clock timer wakes the executor four
    times a second, so that the signal is handled even when the node's own timers stand still
    (``use_sim_time`` with a ``/clock`` that stopped or never came: the Python handler only
    runs when the executor returns, and Ctrl-C and SIGTERM were ignored until SIGKILL; an
    outside review), and a stop not done ``wall_timeout_s`` of wall time after the first
    signal while the node's clock moved less than a tenth of that resolves ``finished`` with
    exit code 1 and an error naming the clock (a clock that runs, however slowly, leaves the
    node's own stop to finish)."""
    import time

    from rclpy.signals import uninstall_signal_handlers

    uninstall_signal_handlers()
    first: list[float] = []

    def handler(signum: int, frame: Any) -> None:
        if not first:
            first.append(time.monotonic())
        stop(f'{signal.Signals(signum).name} received')

    for sig in signals:
        signal.signal(sig, handler)
    finished = getattr(node, 'finished', None)
    if node is None or finished is None:
        return
    from rclpy.clock import Clock, ClockType

    node_clock: list[float] = []

    def watch() -> None:
        if not first or finished.done():
            return
        now = node.get_clock().now().nanoseconds * 1e-9
        if not node_clock:
            node_clock.append(now)
        if time.monotonic() - first[0] <= wall_timeout_s or \
                now - node_clock[0] >= 0.1 * wall_timeout_s:
            return
        sim = node.get_parameter('use_sim_time').value if node.has_parameter(
            'use_sim_time') else False
        node.get_logger().error(
            f'the stop did not finish within {wall_timeout_s:g} s of wall time'
            + (' (use_sim_time is true: the /clock stands still or never came)' if sim
               else '') + ': exiting with the legs where they are (exit code 1)')
        finished.set_result(1)

    node.create_timer(0.25, watch, clock=Clock(clock_type=ClockType.STEADY_TIME))

class InputWatch:
    """Says when a node's inputs do not arrive, on the wall clock (a steady timer: also when
    a simulated clock stands still).

    ``subscriptions`` maps a key to a subscription; the node calls :meth:`seen` with the key
    on each message. ``mode='all'``: one warning when none of them has delivered for
    ``timeout_s`` (since start, or since they stopped: a robot in another namespace, every
    publisher killed); ``'each'``: one warning per subscription that has not delivered for
    ``timeout_s`` (no ``/mocap/body`` for the SLIP fits). The topic names are the resolved
    ones (namespace and remaps). Each silence is said once, and its end at info level.
    Before, ``energy_monitor`` and ``slip_fitter`` said nothing in these cases (an outside
    review of the live graph). ``timeout_s`` 0 turns it off."""

    def __init__(self, node: Any, subscriptions: dict[str, Any], timeout_s: float, *,
                 mode: str = 'all', consequence: str = '') -> None:
        import time

        from rclpy.clock import Clock, ClockType

        self._time = time.monotonic
        self.node, self.subs, self.timeout_s = node, dict(subscriptions), float(timeout_s)
        self.mode, self.consequence = mode, consequence
        start = self._time()
        self.last = {k: start for k in self.subs}
        self.ever = {k: False for k in self.subs}
        self.silent: set[str] = set()
        #: warnings logged (tests)
        self.warnings: list[str] = []
        if self.timeout_s > 0:
            node.create_timer(min(1.0, self.timeout_s / 4.0), self._check,
                              clock=Clock(clock_type=ClockType.STEADY_TIME))

    def seen(self, key: str) -> None:
        """A message arrived on ``key``."""
        self.last[key] = self._time()
        self.ever[key] = True
        back = [k for k in self.silent if k == key or self.mode == 'all']
        if back:
            self.silent.difference_update(back)
            self.node.get_logger().info(
                f'{self.subs[key].topic_name}: messages arrive again')

    def _check(self) -> None:
        now = self._time()
        quiet = [k for k in self.subs if now - self.last[k] >= self.timeout_s]
        if self.mode == 'all':
            groups = [tuple(self.subs)] if len(quiet) == len(self.subs) else []
        else:
            groups = [(k,) for k in quiet]
        for keys in groups:
            if keys[0] in self.silent:
                continue
            self.silent.update(keys)
            names = ', '.join(self.subs[k].topic_name for k in keys)
            never = not any(self.ever[k] for k in keys)
            text = (f'no message on {names} for {self.timeout_s:g} s of wall time'
                    + (' since start' if never else ' (they stopped)' if len(keys) > 1
                       else ' (it stopped)')
                    + (f': {self.consequence}' if self.consequence else '')
                    + '; check that its publishers run in this namespace and ROS domain')
            self.warnings.append(text)
            self.node.get_logger().warning(text)


def publisher_names(node: Any, topic: str) -> str:
    """The graph's publishers of ``topic`` for a message (:func:`hexapod_common.publishers.
    endpoint_names`; a crashed node's endpoint may still be listed), 'unknown' when the graph
    cannot be read."""
    from hexapod_common.publishers import endpoint_names

    try:
        return endpoint_names(node.get_publishers_info_by_topic(topic))
    except Exception:   # noqa: BLE001 - names for a message only
        return 'unknown'


class PublishersWatch:
    """Logs an error, once per episode, when several live publishers interleave on one
    subscribed topic, told from the messages' publication sequence numbers
    (:mod:`hexapod_common.publishers`; a crashed publisher's endpoint, which the graph lists
    for its DDS lease, is not one). The subscription's callback takes the message info
    (two arguments) and passes it to :meth:`add`. It only says so: every message is still
    used (:class:`FirstPublisherWatch` also drops the other publishers' messages)."""

    def __init__(self, node: Any, consequence: str) -> None:
        from hexapod_common.publishers import PublisherSequences

        self.node, self.consequence = node, consequence
        self.sequences = PublisherSequences()
        self.subscription: Any = None
        #: errors logged (one per episode)
        self.reported = 0

    @property
    def topic(self) -> str:
        """The subscription's resolved topic name ('?' before it is set)."""
        return self.subscription.topic_name if self.subscription is not None else '?'

    def _consequence(self) -> str:
        """What the error says follows from the several publishers."""
        return self.consequence

    def add(self, info: Any) -> bool:
        """One message's info; True when it starts an episode of several publishers."""
        from hexapod_common.publishers import publication_sequence

        if not self.sequences.add(publication_sequence(info)):
            return False
        self.reported += 1
        topic = self.topic
        names = publisher_names(self.node, topic)
        self.node.get_logger().error(
            f'several live publishers on {topic} (their messages\' sequence numbers '
            f'interleave; publishers in the graph: {names}): {self._consequence()}')
        return True


class FirstPublisherWatch(PublishersWatch):
    """A :class:`PublishersWatch` for a command topic that applies one publisher only: the
    one that was there first (:class:`hexapod_common.publishers.FirstPublisherGate`; the
    drivers' ``joint_commands``). The subscription's callback passes each message's info (and
    its ``header.frame_id``, which names a gait node in the messages) to :meth:`admit` and
    applies the message only when it returns True.

    Only while the numbers show several publishers interleaving (an episode of
    :class:`~hexapod_common.publishers.PublisherSequences`: two switch backs within its
    window) is anything dropped: one publisher's messages always pass, whatever its send
    clock or losses do to the gate's series (review J5: a sender's clock stepping back 1 s
    dropped 49 of a lone gait node's commands, an NTP step forward 3,000). The newcomer's
    first one or two messages, before its numbers have interleaved twice, are applied.

    Logged: the error of several publishers (once per episode) says which one is followed,
    that the other's commands are ignored and how many so far; when the episode ends (the
    numbers calm again, :class:`~hexapod_common.publishers.PublisherSequences`) a warning
    sums up the commands ignored; a switch to another publisher (the followed one silent
    :data:`~hexapod_common.publishers.FOLLOWED_QUIET_S`, or another that started first) is
    said too (info when nothing was dropped: a respawned publisher). A middleware without
    sequence numbers: every message is applied, as before. The quiet time is measured on the
    steady clock (also under ``use_sim_time``)."""

    def __init__(self, node: Any, what: str = 'commands') -> None:
        import time

        from hexapod_common.publishers import FirstPublisherGate

        super().__init__(node, '')
        self.what = what
        self.gate = FirstPublisherGate()
        #: the receiver's clock for the gate [s] (steady; tests may replace it)
        self.clock: Callable[[], float] = time.monotonic
        self._dropped_before = 0      # the drops before the current episode
        #: messages dropped (the gate said another's, during an episode)
        self.dropped = 0

    def _describe(self, ident: int | None = None) -> str:
        s = self.gate.series(ident)
        if s is None:
            return 'none yet'
        heard = max(0.0, self.clock() - s.first_arrival)
        return ((f'frame_id {s.label!r}, ' if s.label else '')
                + f'at message number {s.last_seq}, heard for {heard:.1f} s')

    def _consequence(self) -> str:
        n = self.dropped - self._dropped_before
        return (f'only the {self.what} of the publisher that was there first are applied '
                f'({self._describe()}); the other\'s {self.what} are ignored ({n} dropped so '
                'far); stop all but one')

    def admit(self, info: Any, label: str = '') -> bool:
        """One message's info (and label): True to apply it, False to drop it (another
        publisher's). Logs as the class says."""
        from hexapod_common.publishers import publication_sequence, source_time

        ok = self.gate.admit(publication_sequence(info), source_time(info), self.clock(),
                             str(label or ''))
        was = self.sequences.interleaving
        self.add(info)
        several = self.sequences.interleaving
        # one publisher (no episode): its message passes whatever the gate's series say
        ok = ok or not several
        if not ok:
            self.dropped += 1
        log = self.node.get_logger()
        if was and not several:
            n = self.dropped - self._dropped_before
            self._dropped_before = self.dropped
            log.warning(f'{self.topic}: one publisher again; {n} {self.what} of the other '
                        f'publisher(s) were ignored in that episode (followed: '
                        f'{self._describe()})')
        for sw in self.gate.take_switches():
            why = (f'the followed publisher was silent for {sw.silent_s:.2f} s'
                   if sw.reason == 'quiet' else
                   'another publisher heard at the same time started first')
            text = f'{self.topic}: {why}: now following another ({self._describe(sw.new)}'
            if several:
                log.warning(f'{text}; its {self.what} were ignored while the other was '
                            'followed)')
            else:
                log.info(f'{text})')
        return ok


#: set to get the traceback of a start-up failure instead of its one-line summary
DEBUG_ENV = 'HEXAPOD_DEBUG'

#: Subscriptions to sensor streams: best effort matches both best-effort and reliable
#: publishers (a reliable subscription would not connect to a best-effort driver); deep enough
#: that a busy executor does not lose samples at 100-200 Hz.
SENSOR_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=200,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

#: Publishers of this graph: reliable, which any subscriber (reliable or best effort) accepts.
RELIABLE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=200,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

#: Latched state such as ``/bench/session``: late joiners get the last message.
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def param(default: Any, description: str, *, validate: Callable[[Any], str | None] | None = None,
          read_only: bool = False, live: bool = False, finite: bool = True) -> Any:
    """Declare one parameter field of a node's frozen dataclass.

    ``validate`` returns None when the value is fine, else the reason it is refused.
    ``live``: a run-time change takes effect (the node reads ``node.params`` at each use);
    without it, and without an ``on_change`` handler, the parameter is read only (module doc).
    ``finite=False`` lets a float parameter be NaN or infinite.
    """
    meta = {'description': description, 'validate': validate, 'read_only': read_only,
            'live': live, 'finite': finite}
    if isinstance(default, (list, tuple)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _default_of(fld: dataclasses.Field) -> Any:
    if fld.default is not dataclasses.MISSING:
        return fld.default
    if fld.default_factory is not dataclasses.MISSING:
        return fld.default_factory()
    raise ParameterError(f'parameter {fld.name!r} has no default')


def _coerce(name: str, value: Any, default: Any) -> Any:
    """Accept ints for float parameters (YAML writes 1 for 1.0); refuse other type changes."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ParameterError(f'parameter {name!r}: expected a bool, got {value!r}')
        return value
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, (list, tuple)):
        if default and all(isinstance(d, float) for d in default):
            value = [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                     for v in value]
        return type(default)(value)
    if not isinstance(value, type(default)):
        raise ParameterError(
            f'parameter {name!r}: expected {type(default).__name__}, got {value!r}')
    return value


def _not_finite(value: Any) -> str | None:
    """Why a float (or float list) value is refused as not finite, else None."""
    values = value if isinstance(value, (list, tuple)) else (value,)
    bad = [v for v in values if isinstance(v, float) and not math.isfinite(v)]
    return f'expected a finite number, got {bad[0]}' if bad else None


def validate_params(cls: type[T], values: dict[str, Any]) -> T:
    """Build the frozen parameter dataclass from ``values``, running every validator."""
    kwargs = {}
    for fld in dataclasses.fields(cls):  # type: ignore[arg-type]
        default = _default_of(fld)
        value = _coerce(fld.name, values.get(fld.name, default), default)
        if fld.metadata.get('finite', True) and (reason := _not_finite(value)):
            raise ParameterError(f'parameter {fld.name!r} = {value!r} refused: {reason}')
        check = fld.metadata.get('validate')
        if check is not None and (reason := check(value)):
            raise ParameterError(f'parameter {fld.name!r} = {value!r} refused: {reason}')
        kwargs[fld.name] = value
    return cls(**kwargs)


def params_from_overrides(cls: type[T], overrides: Sequence[Any] | None) -> T:
    """Parameter dataclass from rclpy ``Parameter`` overrides, without a node (for tests)."""
    return validate_params(cls, {p.name: p.value for p in overrides or ()})


#: parameters rclpy itself (or its QoS overrides) takes on every node
_RCLPY_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def unknown_overrides(overrides: Iterable[str], declared: Sequence[str]) -> dict[str, str]:
    """For each start-up override (``-p name:=value``) the node does not declare, why it is
    ignored, naming the closest declared name: ``-p mas:=3.0`` ran on the default mass, and
    ``-p sped:=0.9`` walked at the default speed, without a word (an outside review)."""
    import difflib

    out = {}
    for name in sorted(set(overrides) - set(declared)):
        if name in _RCLPY_PARAMETERS or name.startswith('qos_overrides.'):
            continue
        # a close name is a typo, worth a warning; another is likely a shared parameter
        # file's (``/**``) for other nodes: said once at info level (review D: 'port' read
        # "did you mean 'preset'?" on every node of a one-file launch)
        near = difflib.get_close_matches(name, declared, n=1, cutoff=0.8)
        out[name] = (f'parameter {name!r} is not one of this node\'s: ignored' +
                     (f' (did you mean {near[0]!r}?)' if near else
                      ' (another node\'s, from a shared parameter file? --help lists this '
                      'node\'s)'))
    return out


def declare_params(node: Any, cls: type[T], *,
                   on_change: Callable[[T], str | None] | None = None) -> T:
    """Declare every field of ``cls`` on ``node`` and read the values back into ``cls``.

    On a run-time change the new set is validated as a whole; ``on_change`` receives the new
    dataclass, applies it, or refuses it by returning a reason. The accepted value is stored in
    ``node.params``. Without ``on_change`` only ``live`` fields are writable; with it, every
    field not ``read_only`` (module doc). A start-up value of the wrong type raises
    :class:`ParameterError`.
    """
    from rclpy.exceptions import InvalidParameterTypeException
    from rclpy.parameter import Parameter

    values = {}
    widened: dict[str, Parameter.Type] = {}   # float fields that also take a whole number
    for fld in dataclasses.fields(cls):  # type: ignore[arg-type]
        default = _default_of(fld)
        writable = bool(fld.metadata.get('live', False)) or on_change is not None
        descriptor = ParameterDescriptor(
            description=fld.metadata.get('description', ''),
            read_only=bool(fld.metadata.get('read_only', False)) or not writable,
        )
        declared = default if not isinstance(default, tuple) else list(default)
        kind = Parameter.Type.from_parameter_value(declared)
        if kind in (Parameter.Type.DOUBLE, Parameter.Type.DOUBLE_ARRAY):
            widened[fld.name] = kind
        try:
            node.declare_parameter(fld.name, declared, descriptor)
        except InvalidParameterTypeException as err:
            # ``-p mass:=2`` is an INTEGER override of a DOUBLE parameter: take it as 2.0
            value = _override_value(node, fld.name)
            as_float = _widen(kind, value)
            if as_float is None:
                raise ParameterError(f'parameter {fld.name!r} refused: '
                                     f'{err.args[0] if err.args else err}') from err
            node.declare_parameter(fld.name, as_float, descriptor, ignore_override=True)
        values[fld.name] = node.get_parameter(fld.name).value
    params = validate_params(cls, values)
    node.params = params
    node.unknown_parameters_ = unknown_overrides(
        getattr(node, '_parameter_overrides', {}) or {}, list(values))
    for why in node.unknown_parameters_.values():
        if 'did you mean' in why:
            node.get_logger().warning(why)
        else:
            node.get_logger().info(why)

    def _on_set(parameters: list[Any]) -> SetParametersResult:
        current = dataclasses.asdict(node.params)  # type: ignore[call-overload]
        current.update({p.name: p.value for p in parameters if p.name in current})
        try:
            new = validate_params(cls, current)
        except ParameterError as err:
            return SetParametersResult(successful=False, reason=str(err))
        if on_change is not None and (reason := on_change(new)):
            return SetParametersResult(successful=False, reason=reason)
        node.params = new
        return SetParametersResult(successful=True)

    def _pre_set(parameters: list[Any]) -> list[Any]:
        # a run-time whole number for a float parameter (``ros2 param set /n mass 2``)
        out = []
        for p in parameters:
            as_float = _widen(widened[p.name], p.value) if p.name in widened else None
            out.append(p if as_float is None or p.type_ == widened[p.name]
                       else Parameter(p.name, widened[p.name], as_float))
        return out

    node.add_pre_set_parameters_callback(_pre_set)
    node.add_on_set_parameters_callback(_on_set)
    return params


def _widen(kind: Any, value: Any) -> Any:
    """``value`` as a float (or float list) when ``kind`` is DOUBLE (DOUBLE_ARRAY) and
    ``value`` is a whole number (a list of them), else None."""
    from rclpy.parameter import Parameter

    def whole(v: Any) -> bool:
        return isinstance(v, numbers.Integral) and not isinstance(v, bool)

    if kind == Parameter.Type.DOUBLE and whole(value):
        return float(value)
    if kind == Parameter.Type.DOUBLE_ARRAY and not isinstance(value, (str, bytes)) \
            and hasattr(value, '__iter__') and all(whole(v) for v in value):
        return [float(v) for v in value]
    return None


def _override_value(node: Any, name: str) -> Any:
    """The start-up override of ``name`` (``-p name:=...``), read by declaring the parameter
    with dynamic typing, then undeclaring it; None if there is none."""
    probe = ParameterDescriptor(dynamic_typing=True)
    try:
        node.declare_parameter(name, None, probe)
        return node.get_parameter(name).value
    except Exception:   # noqa: BLE001 - no readable override: the caller refuses the value
        return None
    finally:
        if node.has_parameter(name):
            node.undeclare_parameter(name)


def run_node(node_factory: Callable[..., Any], args: Sequence[str] | None = None, *,
             params: type | None = None) -> int:
    """The Jazzy ``main()``: init, spin, clean shutdown on Ctrl-C or external shutdown.

    ``-h``/``--help`` before any ``--ros-args`` prints the node's name, purpose and parameters
    (:func:`node_help`; ``params`` is the node's parameter dataclass, found from the factory
    when not given) and returns 0 without initialising rclpy: no node, no publisher.

    A node that has a ``finished`` attribute (an ``rclpy.task.Future``) is spun until that
    future is done, and its result is the exit code (a plan that ends, a replay that finishes).
    After a stop, a node's ``exit_code_on_stop`` (set by its ``destroy_node``) is the exit code;
    a stop while the node is built gives the ``exit_code_on_stop`` of the exception its
    constructor raised after cleaning up (0 when it has none).

    Any error while the node is built (a refused parameter, a missing file, a bus that does
    not open) is printed as one line naming the node and the error and gives exit code 2;
    with ``HEXAPOD_DEBUG=1`` the traceback is raised instead. So are ROS arguments that rcl
    refuses (a params file missing or not YAML) and arguments outside ``--ros-args`` (a
    ``-p NAME:=VALUE`` typed without it was ignored).

    Ctrl-C shuts the context down from rclpy's signal handler while a callback may be
    publishing or the executor building its wait set: the ``RCLError`` or ``InvalidHandle``
    (or the node being built) that follows while the context is no longer valid is a clean
    stop (exit 0), as is a second ``KeyboardInterrupt`` during the clean-up.
    """
    if wants_help(sys.argv[1:] if args is None else args):
        try:
            print(node_help(node_factory, params), flush=True)
        except BrokenPipeError:
            # the reader has gone (``NODE --help | head -1``): no traceback, and no second
            # one when the interpreter flushes stdout at exit
            try:
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            except (OSError, ValueError):
                pass
        return 0

    import rclpy
    from rclpy.executors import ExternalShutdownException

    from hexapod_common import stop_signals

    def stopped_before_start() -> int | None:
        # a stop signal noted by the console script's first statements (stop_signals): a
        # node started in the background by a script ignored SIGINT until rclpy.init, and ran
        # on (an outside review); now it stops before it starts, with one line
        sig = stop_signals.received() if stop_signals.caught_program() else None
        if sig is None:
            return None
        rclpy.try_shutdown()
        print(f'{_program_name(node_factory)}: {signal.Signals(sig).name} before the node '
              'started: stopped', file=sys.stderr)
        return stop_signals.EXIT_CODES[sig]

    if (code := stopped_before_start()) is not None:
        return code
    stop_errors = stopping_errors()
    argv = list(sys.argv if args is None else args)
    try:
        # a params file that is missing or not YAML, a malformed remap: rcl refuses them here
        # (it was a traceback and exit 1)
        rclpy.init(args=argv)
    except Exception as err:
        if os.environ.get(DEBUG_ENV):
            raise
        print(f'{_program_name(node_factory)}: error: the ROS arguments were refused: '
              f'{str(err).splitlines()[0] if str(err) else type(err).__name__} (set '
              f'{DEBUG_ENV}=1 for the traceback)', file=sys.stderr)
        return 2
    if (code := stopped_before_start()) is not None:
        return code     # noted while rclpy installed its own handlers
    from rclpy.utilities import remove_ros_args

    stray = remove_ros_args(args=argv)[1:]
    if stray:
        # '-p speed:=0.3' or '--speed 0.3' without --ros-args were ignored without a word
        # and the robot walked the defaults (an outside review)
        rclpy.try_shutdown()
        print(f'{_program_name(node_factory)}: error: unrecognized argument(s) '
              f'{" ".join(stray)}: node parameters go after --ros-args (e.g. '
              '`--ros-args -p NAME:=VALUE`); --help lists them', file=sys.stderr)
        return 2
    node = None
    start_code = 0      # a stop while the node was built: the code its clean-up gave it
    try:
        try:
            node = node_factory()
        except (KeyboardInterrupt, ExternalShutdownException) as err:
            start_code = _stop_code(err)
            raise
        except Exception as err:
            if isinstance(err, stop_errors) and not rclpy.ok():
                # Ctrl-C while the node was being built: a stop, not an error (exit 0, or
                # the code its clean-up gave: dynamixel_driver's torque off not confirmed)
                return _stop_code(err)
            if os.environ.get(DEBUG_ENV):
                raise
            what = str(err) if isinstance(err, ParameterError) else \
                f'{type(err).__name__}: {err}'
            print(f'{_program_name(node_factory)}: error: {what} (set {DEBUG_ENV}=1 for the '
                  'traceback)', file=sys.stderr)
            return 2
        finished = getattr(node, 'finished', None)
        try:
            if finished is None:
                rclpy.spin(node)
            else:
                # A node with a job that ends (e.g. a bench plan) resolves ``node.finished``
                # with its exit code; spin until then.
                spin_until_done(node, finished)
                if finished.done():
                    return int(finished.result() or 0)
        except stop_errors:
            if rclpy.ok():
                raise    # not a shutdown: a real error
            # the context was shut down under a callback or the wait set (Ctrl-C): a stop
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        close_node(node)
    # a node whose clean-up in destroy_node failed sets ``exit_code_on_stop`` (dynamixel_driver:
    # torque off at shutdown not confirmed); an outside review: it exited 0
    return _stop_code(node) or start_code


def _stop_code(obj: Any) -> int:
    """``obj.exit_code_on_stop`` when it is an int (a node after its clean-up, or the stop
    exception its constructor raised after cleaning up), else 0."""
    code = getattr(obj, 'exit_code_on_stop', 0)
    return code if isinstance(code, int) and not isinstance(code, bool) else 0


def spin_until_done(node: Any, future: Any) -> None:
    """Spin ``node`` until ``future`` is done or the context shuts down.

    Not ``rclpy.spin_until_future_complete``: rclpy 7's executor adds a done callback to the
    future on every ``spin_once``, and a node's ``finished`` stays pending for its whole
    life, so the list grew by one closure per callback run: ``gait_scheduler`` grew by
    270 MB an hour (an outside review's 20-minute run; 17,010 callbacks after 20 s of a 1 ms
    timer), and ``dynamixel_driver`` and ``bench_sequencer`` the same. One done callback
    wakes the executor here."""
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    future.add_done_callback(lambda _f: executor.wake())
    try:
        while node.context.ok() and not future.done() and not future.cancelled():
            # the timeout bounds a wake lost between the check and the wait
            executor.spin_once(timeout_sec=0.5)
    finally:
        try:
            executor.shutdown(timeout_sec=0)
        except Exception:  # noqa: BLE001 - the context may be gone already (Ctrl-C)
            pass


def stopping_errors() -> tuple[type[BaseException], ...]:
    """What rclpy raises once the context is shut down under a callback or a clean-up."""
    from rclpy.exceptions import InvalidHandle
    from rclpy.impl.implementation_singleton import rclpy_implementation

    return (rclpy_implementation.RCLError, InvalidHandle)


def close_node(node: Any) -> None:
    """Destroy ``node`` and shut rclpy down, through a late Ctrl-C or an invalid context."""
    import rclpy

    for step in ((node.destroy_node,) if node is not None else ()) + (rclpy.try_shutdown,):
        for _ in range(3):   # a KeyboardInterrupt pending from the Ctrl-C lands here
            try:
                step()
                break
            except KeyboardInterrupt:
                continue
            except stopping_errors():
                break        # already gone with the context


def wants_help(args: Sequence[str]) -> bool:
    """True when ``-h`` or ``--help`` comes before any ``--ros-args`` in ``args``."""
    for arg in args:
        if arg == '--ros-args':
            return False
        if arg in ('-h', '--help'):
            return True
    return False


def find_params_class(node_factory: Callable[..., Any]) -> type | None:
    """The parameter dataclass a node class passes to :func:`declare_params`, else None.

    Read from the ``declare_params(self, Cls`` call in the ``__init__`` of the class or its
    bases; else the one dataclass of :func:`param` fields in the factory's module.
    """
    import importlib
    import re

    for cls, source in _init_sources(node_factory):
        module = importlib.import_module(getattr(cls, '__module__', '') or '__main__')
        for name in re.findall(r'declare_params\(\s*self\s*,\s*(\w+)', source):
            found = getattr(module, name, None)
            if _is_params_class(found):
                return found
    module = sys.modules.get(getattr(node_factory, '__module__', '') or '')
    candidates = [v for v in vars(module).values()
                  if _is_params_class(v) and v.__module__ == module.__name__] if module else []
    return candidates[0] if len(candidates) == 1 else None


def _init_sources(node_factory: Callable[..., Any]) -> Iterator[tuple[Any, str]]:
    """``(class, source of its __init__)`` of a node class and its bases (or of a factory
    function), skipping those without readable source."""
    import inspect

    if inspect.isclass(node_factory):
        classes: tuple[Any, ...] = inspect.getmro(node_factory)
    else:   # a factory function (signal handlers installed): also the class it returns
        ret = inspect.signature(node_factory).return_annotation
        if isinstance(ret, str):
            ret = getattr(node_factory, '__globals__', {}).get(ret)
        classes = (node_factory, *(inspect.getmro(ret) if inspect.isclass(ret) else ()))
    for cls in classes:
        init = getattr(cls, '__init__', None) if inspect.isclass(cls) else cls
        try:
            yield cls, inspect.getsource(init)  # type: ignore[arg-type]
        except (OSError, TypeError):
            continue


def writable_params(node_factory: Callable[..., Any], cls: type) -> set[str]:
    """Names of ``cls``'s fields a run-time ``ros2 param set`` changes (module doc): the
    ``live`` ones, and every field not ``read_only`` when the node's ``declare_params`` call
    passes ``on_change`` (read from its source, as :func:`find_params_class`)."""
    import re

    fields = dataclasses.fields(cls)  # type: ignore[arg-type]
    live = {f.name for f in fields if f.metadata.get('live', False)}
    for _klass, source in _init_sources(node_factory):
        call = re.search(r'declare_params\(\s*self\s*,\s*' + re.escape(cls.__name__) +
                         r'\b([^)]*)\)', source)
        if call is not None:
            if 'on_change' in call.group(1):
                return live | {f.name for f in fields if not f.metadata.get('read_only')}
            return live
    return live


def _is_params_class(obj: Any) -> bool:
    """A dataclass whose every field was declared with :func:`param`."""
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):
        return False
    fields = dataclasses.fields(obj)
    return bool(fields) and all('description' in f.metadata for f in fields)


def _first_line(doc: str | None) -> str:
    return (doc or '').strip().split('\n\n')[0].replace('\n', ' ').strip()


def node_help(node_factory: Callable[..., Any], params: type | None = None) -> str:
    """``--help`` text of a node: its name, one line of purpose, its parameters.

    The purpose is the first sentence of the class docstring when it names the node
    (````sim_robot``: ...``), else of the module docstring; parameters come from ``params``
    (or :func:`find_params_class`) with their defaults and descriptions.
    """
    import re
    import textwrap

    cls_doc = _first_line(getattr(node_factory, '__doc__', None))
    module = sys.modules.get(getattr(node_factory, '__module__', '') or '')
    purpose = cls_doc if cls_doc.startswith('``') else \
        _first_line(getattr(module, '__doc__', None)) or cls_doc
    named = re.match(r'``([\w/]+)``(?: node)?:\s*', purpose)
    name = named.group(1) if named else _program_name(node_factory)
    purpose = purpose[named.end():] if named else purpose
    purpose = re.sub(r':\w+:`~?([^`]+)`', r'\1', purpose).replace('``', '')
    lines = [f'usage: {name} [-h] [--ros-args [-p NAME:=VALUE]... [--params-file FILE]]', '',
             f'{name}: {purpose}' if purpose else name, '']
    cls = params or find_params_class(node_factory)
    if cls is None:
        lines.append('parameters: see the README')
        return '\n'.join(lines)
    lines.append('parameters (--ros-args -p NAME:=VALUE; default after =; "settable" ones also '
                 'take `ros2 param set` while running, the others refuse it):')
    writable = writable_params(node_factory, cls)
    for fld in dataclasses.fields(cls):  # type: ignore[arg-type]
        default = _default_of(fld)
        shown = list(default) if isinstance(default, tuple) else default
        kind = type(default).__name__ if not isinstance(default, (list, tuple)) else 'list'
        tag = ', settable' if fld.name in writable else ''
        lines.append(f'  {fld.name} = {shown!r} ({kind}{tag})')
        lines.extend(textwrap.wrap(fld.metadata.get('description', ''), width=92,
                                   initial_indent=' ' * 6, subsequent_indent=' ' * 6))
    return '\n'.join(lines)


def overridden(node: Any, name: str) -> bool:
    """True when parameter ``name`` was given at start-up (``-p``, a params file, or
    ``parameter_overrides``) rather than left at its default."""
    return name in getattr(node, '_parameter_overrides', {})


def _program_name(node_factory: Callable[..., Any]) -> str:
    """The console script's name (``energy_monitor``), else the factory's."""
    name = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ''
    if not name or name.endswith('.py') or name.startswith('-') or name == 'pytest':
        name = getattr(node_factory, '__name__', 'node')
    return name


def mocap_msg_class(name: str) -> Any:
    """The rclpy message class of a ``mocap_type`` parameter value
    (:data:`hexapod_common.conversions.MOCAP_TYPES`: PoseStamped, TransformStamped,
    PoseWithCovarianceStamped, Odometry); ValueError on another name."""
    import importlib

    from hexapod_common.conversions import MOCAP_TYPES

    if name not in MOCAP_TYPES:
        raise ValueError(f'mocap_type must be one of {", ".join(MOCAP_TYPES)}, got {name!r}')
    pkg, _, cls = MOCAP_TYPES[name].split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), cls)
