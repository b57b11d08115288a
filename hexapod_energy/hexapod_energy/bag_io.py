"""Read bench and robot bags into the arrays the energy analysis needs.

Uses ``hexapod_common.bags.open_reader`` (rosbags, definitions from the bag) and the message
converters of ``hexapod_common.conversions``; all times are header stamps [s].

Bench bags need ``/battery_state``, ``/bench/ground_force``, ``/bench/leg_tip`` (else the
tip height from ``/joint_states`` by forward kinematics) and ``/bench/session``, and use the
bench leg's ``/gait/phase`` when present (the phase split); robot bags need ``/battery_state``
and ``/gait/phase`` (``/joint_states`` with efforts and ``/mocap/body`` are used when
present).  A missing topic raises
:class:`~hexapod_energy.errors.BagContentError` naming what is missing and what is there.

Bench bags (:func:`read_bench_bag`) take the same zero-stamp fallback on every topic they
read. Robot bags recorded by other tools (:func:`read_robot_bag`): a message whose header stamp is
zero (drivers that never fill it) takes the bag's receive time; samples are fed in header-stamp
order (recorders store arrival order, a few ms off); a stamped message recorded twice (same
topic, same bytes) counts once; a bad message (NaN voltage or current, array lengths that
disagree with the names) is dropped, and a bag whose every ``/battery_state`` message is
dropped is refused (no input power without current). Each fallback is listed in
``RobotRun.extra['notes']`` (``energy.json`` ``warnings``).

Which cycles (``cycle_source='auto'``) is decided from the topics that have messages, counted
while reading: a ``/gait/phase`` connection without any (usable) message, as ``ros2 bag record
-a`` leaves for an advertised but silent topic, does not count; the cycles then come from the
joint positions, with the note ``/gait/phase recorded but without messages: cycle boundaries
from the joint positions``. ``/joint_states`` efforts count (``has_effort``, P_out not NaN) only
when they gave a joint power: with velocities, or without them from position differences
(:mod:`hexapod_energy.descriptors`, note :data:`~hexapod_energy.descriptors.POSITION_POWER_NOTE`);
efforts alone leave P_out unknown (NaN), never 0 W.
"""

from __future__ import annotations

import array
import dataclasses
import json
import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hexapod_common.conversions import LegJointFilter, MOCAP_TF_ENV
from hexapod_common.series import robust_sigma
from hexapod_energy.errors import BagContentError
from hexapod_energy.single_leg import (MAX_POWER_LAG_S, PhaseSample, align_offset_sessions_s,
                                       phase_powers, power_label_lag_s, stance_mask)

if TYPE_CHECKING:   # the bag reader (rosbags) is imported where a bag is read
    from hexapod_common.bags import SampleColumns

__all__ = [
    'BENCH_LOAD_MAX_KG',
    'BENCH_TOPICS',
    'PHASE_SPLITS',
    'ROBOT_TOPICS',
    'BenchData',
    'BenchSessionSpec',
    'RobotMass',
    'RobotRun',
    'bench_load_problem',
    'bench_phase_samples',
    'declared_robot_mass',
    'force_sign_factor',
    'merge_bench_data',
    'read_bench_bag',
    'read_bench_sessions_file',
    'read_robot_bag',
    'read_robot_segments',
    'resolve_robot_mass',
]

BENCH_TOPICS = ('/battery_state', '/bench/ground_force', '/bench/leg_tip', '/bench/session')
ROBOT_TOPICS = ('/battery_state', '/gait/phase')
#: fraction of a gait cycle by which a bench session may fall short of a whole cycle count
#: and still count it (stamp jitter); the window is then clipped at the session's end
CYCLE_TOLERANCE = 0.02


def _check_topics(reader: Any, required: Sequence[str], path: str) -> None:
    present = sorted({c.topic for c in reader.connections})
    missing = [t for t in required if t not in present]
    if missing:
        raise BagContentError(
            f'bag {path} lacks topic(s) {missing} needed for this analysis; it has {present}'
            + namespace_hint(missing, present))


def namespace_hint(missing: Sequence[str], present: Sequence[str]) -> str:
    """'; recorded under a namespace? ...' when every missing topic is present under one
    common prefix (a graph run in a namespace, e.g. hexapod-demo's /demo_<pid>), else ''."""
    prefixes = set()
    for topic in missing:
        found = [p[:-len(topic)] for p in present if p.endswith(topic) and len(p) > len(topic)]
        if len(found) != 1:
            return ''
        prefixes.add(found[0])
    if len(prefixes) != 1:
        return ''
    ns = prefixes.pop()
    return f'; recorded under a namespace? give --namespace {ns}'


def _custom_data(reader: Any) -> dict[str, str]:
    """The bags' ``custom_data`` (metadata.yaml). rosbags keeps it at
    ``Reader.storage.metadata.custom`` (0.10+; ``Reader.metadata`` before): reading only the
    latter returned nothing, so a bag's recorded payload was never used (an outside review:
    CoT/M 23 % high for a 0.5 kg payload the bag declared)."""
    out: dict[str, str] = {}
    for r in getattr(reader, 'readers', []):
        for holder in (r, getattr(r, 'storage', None)):
            meta = getattr(holder, 'metadata', None) if holder is not None else None
            custom = getattr(meta, 'custom', None) if meta is not None else None
            if isinstance(custom, dict):
                out.update({str(k): str(v) for k, v in custom.items()})
    return out


def _find_number(custom: dict[str, str], keys: Sequence[str]) -> float | None:
    for key in keys:
        if key in custom:
            try:
                return float(custom[key])
            except ValueError:
                pass
    for value in custom.values():
        try:
            doc = json.loads(value)
        except (ValueError, TypeError):
            continue
        stack = [doc]
        while stack:
            d = stack.pop()
            if isinstance(d, dict):
                for key in keys:
                    if isinstance(d.get(key), (int, float)):
                        return float(d[key])
                stack.extend(v for v in d.values() if isinstance(v, dict))
    return None


@dataclass
class BenchData:
    """Streams of one bench bag (arrays (n,), stamps [s])."""

    path: str
    battery_t_s: np.ndarray
    battery_v: np.ndarray
    battery_a: np.ndarray
    force_t_s: np.ndarray
    force_z_n: np.ndarray
    tip_t_s: np.ndarray
    tip_z_m: np.ndarray
    sessions: list[dict[str, Any]] = field(default_factory=list)  # stamp-ordered messages
    notes: list[str] = field(default_factory=list)  # input fallbacks (dropped messages)
    #: the commanded schedule of the bench leg from ``/gait/phase`` (stamps [s], in_stance),
    #: empty without it (:func:`bench_phase_samples` ``phase_split``)
    schedule_t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    schedule_stance: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    #: every ``/gait/phase`` message (n, 6): stamp [s], the walked step frequency [Hz] (0 when
    #: standing: period 0, or step length and height 0), duty factor, step length and height
    #: [m], and a code of every leg's in_stance (constant while the legs stand); the session
    #: frequency is checked against it (:func:`bench_phase_samples`)
    gait_rows: np.ndarray = field(default_factory=lambda: np.zeros((0, GAIT_COLUMNS)))
    #: what must reach ``energy.json`` ``warnings`` (not only the diagnostics' notes)
    warnings: list[str] = field(default_factory=list)
    #: the legs of a several-leg ``/gait/phase``, in the order of its in_stance (the bits of
    #: :attr:`gait_rows`' stance code), and the bench leg among them ('' unknown); for naming
    #: the leg whose schedule agrees with the measured contact (:func:`bench_phase_samples`)
    schedule_legs: tuple[str, ...] = ()
    bench_leg: str = ''
    #: the bench leg's clock at each :attr:`schedule_t_s` (n, 3): its phase
    #: ``(cycle_phase - theta) mod 1``, the period [s] and the duty factor (NaN: not given);
    #: places the phase boundaries between the labels (:func:`bench_phase_samples`). Used only
    #: with one row per label (a schedule replaced without it: the nearest label)
    schedule_clock: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    #: the bench leg's measured coxa, femur and tibia angles from ``/joint_states`` of a bag
    #: without ``/gait/phase`` (stamps [s], (n, 3) [rad]; empty without them, or with several
    #: legs' and no bench leg named): a leg whose joints stop moving pauses
    #: (:func:`_joint_pauses`; or the tip's joints, without ``/bench/leg_tip``)
    joint_t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    joint_q_rad: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


#: columns of :attr:`BenchData.gait_rows`
GAIT_COLUMNS = 6
#: in the warning of a several-leg ``/gait/phase`` whose bench leg is unknown
LEG_UNKNOWN = 'the bench leg is not identified'


#: how :func:`bench_phase_samples` labels stance and swing
PHASE_SPLITS = ('auto', 'schedule', 'contact')


@dataclass(frozen=True)
class BenchSessionSpec:
    """The session of a bench bag recorded without ``/bench/session`` (another lab's bench:
    one bag per session, its load written down by the operator).

    ``frequency_hz`` None: from ``/gait/phase`` (its period) when the bag has it, else from the
    leg tip's height (its step period; a tip that stays within 3 mm is a 0 Hz session).
    ``duty_factor`` None: 0.5 (the phases are split from the force and the tip anyway).
    """

    load_kg: float
    frequency_hz: float | None = None
    duty_factor: float | None = None
    step_length_m: float | None = None
    step_height_m: float | None = None


#: a single-leg bench load above this [kg] is refused as not kilograms: no leg bench carries
#: it (``hexapod-sim bench`` takes up to 5 kg; the paper's stage up to 0.515 kg), while loads
#: written in grams (100 to 500 "kg" for a 2.2 kg robot) passed every check and predicted
#: 39.0 W for 48.3 W
BENCH_LOAD_MAX_KG = 50.0


def bench_load_problem(loads: Sequence[tuple[str, float]], *,
                       robot_mass_kg: float | None = None, robot_what: str = '') -> str:
    """Why the bench loads ``(where, kg)`` cannot be kilograms ('' when they can): one above
    :data:`BENCH_LOAD_MAX_KG`, or above ``robot_mass_kg`` (the robot's mass with its payload
    when given: a leg carries a share of it; ``robot_what`` names the mass)."""
    if not loads:
        return ''
    for where, kg in loads:
        # a negative load was fitted as given (surfaces over -0.515..0 kg, exit 0), a NaN
        # one ended in numpy's "SVD did not converge" (an outside review)
        if not (math.isfinite(kg) and kg >= 0.0):
            return (f'bench load {kg:g} kg ({where}) is not a load: BenchSession load_mass '
                    "and the sessions file's load_kg are the kilograms on the stage, >= 0")
    where, top = max(loads, key=lambda x: x[1])
    limit, what = BENCH_LOAD_MAX_KG, f'{BENCH_LOAD_MAX_KG:g} kg, more than any leg bench carries'
    if robot_mass_kg is not None and robot_mass_kg < limit:
        limit, what = robot_mass_kg, f'the {robot_what or "robot"}\'s {robot_mass_kg:g} kg'
    if not top > limit:
        return ''
    return (f'bench load {top:g} kg ({where}) is above {what}: the loads look like grams. '
            'BenchSession load_mass and the sessions file\'s load_kg are kilograms '
            f'({top:g} g is {top / 1000:g} kg)')


def read_bench_sessions_file(path: str | Path) -> dict[str, BenchSessionSpec]:
    """Bench bags and their sessions from a CSV file: a header with ``bag`` and ``load_kg``
    and optionally ``frequency_hz``, ``duty_factor``, ``step_length_m``, ``step_height_m``
    (the tip path the leg walked: other step geometries are mapped onto it; an empty cell is
    unknown), one row per bag. Relative bag paths are taken from the file's folder (or, when
    not found there, the working directory). Returns ``{bag path: spec}`` in file order."""
    import csv

    src = Path(path)
    try:
        text = src.read_text(encoding='utf-8-sig')   # a spreadsheet's byte-order mark
    except (OSError, UnicodeDecodeError) as err:
        raise BagContentError(f'bench sessions file {path}: cannot read: {err}') from err
    lines = [line for line in text.splitlines()
             if line.strip() and not line.lstrip().startswith('#')]
    # comma, or the semicolon / tab a spreadsheet in another locale writes
    delimiter = max((',', ';', '\t'), key=lambda d: lines[0].count(d)) if lines else ','
    reader = csv.DictReader(lines, delimiter=delimiter)
    if reader.fieldnames:
        reader.fieldnames = [f.strip().lower() for f in reader.fieldnames]
    rows = list(reader)
    if not rows or not {'bag', 'load_kg'} <= set(rows[0]):
        raise BagContentError(f'bench sessions file {path}: expected a CSV header with bag and '
                              'load_kg (optional: frequency_hz, duty_factor, step_length_m, '
                              'step_height_m)')
    out: dict[str, BenchSessionSpec] = {}
    for i, row in enumerate(rows, start=2):
        def num(key: str, required: bool = False) -> float | None:
            cell = (row.get(key) or '').strip()
            if not cell:
                if required:
                    raise BagContentError(f'bench sessions file {path}, line {i}: {key} is '
                                          'empty')
                return None
            try:
                value = float(cell)
            except ValueError:
                raise BagContentError(f'bench sessions file {path}, line {i}: {key} = '
                                      f'{cell!r} is not a number') from None
            if not math.isfinite(value) or value < 0:
                raise BagContentError(f'bench sessions file {path}, line {i}: {key} = '
                                      f'{cell!r}: expected a finite value >= 0')
            return value

        bag = (row.get('bag') or '').strip()
        if not bag:
            raise BagContentError(f'bench sessions file {path}, line {i}: bag is empty')
        where = src.parent / bag
        bag_path = str(where if where.exists() or Path(bag).is_absolute() else Path(bag))
        load = num('load_kg', required=True)
        assert load is not None
        beta = num('duty_factor')
        if beta is not None and not 0.0 < beta < 1.0:
            raise BagContentError(f'bench sessions file {path}, line {i}: duty_factor = '
                                  f'{beta}: expected 0 < beta < 1')
        out[bag_path] = BenchSessionSpec(load, num('frequency_hz'), beta, num('step_length_m'),
                                         num('step_height_m'))
    why = bench_load_problem([(f'bag {Path(b).name}', s.load_kg) for b, s in out.items()])
    if why:
        raise BagContentError(f'bench sessions file {path}: {why}')
    return out


def _tip_frequency_hz(t_s: np.ndarray, z_m: np.ndarray) -> tuple[float, str]:
    """Step frequency of a bench session from its leg tip's height: 0 when the tip stays
    within 3 mm (5-95 percentiles), else the autocorrelation period (:mod:`.cycles`);
    NaN and the reason when no period is clear."""
    from hexapod_energy.cycles import CycleSettings, estimate_period, resample_uniform

    if z_m.size < 10:
        return math.nan, 'too few leg tip samples'
    span = float(np.subtract(*np.percentile(z_m, [95, 5])))
    if span < 0.003:
        return 0.0, f'the leg tip stays within {span * 1e3:.1f} mm'
    settings = CycleSettings(grid_dt_s=0.01, min_amplitude_rad=1e-4, max_period_s=4.0,
                             max_span_s=max(40.0, float(t_s[-1] - t_s[0])))
    est = estimate_period(resample_uniform(t_s, z_m[:, None], 0.01), settings)
    if not est.periodic:
        return math.nan, f'the leg tip height shows no clear period ({est.status})'
    return 1.0 / est.period_s, f'leg tip period {est.period_s:.4g} s'


def read_bench_bag(path: str | Path, session: BenchSessionSpec | None = None, *,
                   leg_dh: Any = None, leg_name: str = 'AntBot',
                   bench_leg: str | None = None) -> BenchData:
    """Read one bench bag's streams.

    The bench leg (whose commanded stance on ``/gait/phase`` splits stance from swing): the
    only leg of a one-leg ``/gait/phase`` (this project's simulators); on a ``/gait/phase`` of
    several legs (the project's ``gait_scheduler`` has no one-leg mode) ``bench_leg`` when
    given (``energy --bench-leg``), else the one leg whose coxa, femur and tibia joints are on
    ``/joint_states``, with or without ``/bench/leg_tip`` (noted). When none names it, stance
    and swing are split by contact, and that is a warning (:attr:`BenchData.warnings`: on the
    outside review's emulated bench the contact split read P_stance +19..+37 % and P_swing
    -18..-42 % against the emulator's V*I split by the leg's schedule).

    A bench without motion capture of the leg tip (no ``/bench/leg_tip``) but with the servos'
    ``/joint_states`` takes the tip height from the joint angles by forward kinematics of the
    leg (``leg_dh``: a ``hexapod_gait`` DHParameters, default AntBot's; ``leg_name`` for the
    note): one leg's ``<leg>_coxa``, ``<leg>_femur`` and ``<leg>_tibia``, height in the leg's
    base frame (the stance split takes the tip's lowest band, so the frame's origin does not
    matter), noted.

    ``session``: the bag has no ``/bench/session`` (:class:`BenchSessionSpec`, from
    ``energy --bench-sessions``); the bag is one session, walking where its leg tip steps
    (standing before and after cut off, noted: :func:`_session_from_spec`). With
    ``/bench/session``, its messages are checked against the tip's steps (lost messages:
    :func:`_repair_sessions`, warned). Loads that look like grams are refused
    (:func:`bench_load_problem`). A bag that
    records ``/bench/session`` and is given a ``session`` too is refused (which one holds?).

    A bad message (NaN voltage or current, a NaN force or tip height) is dropped and counted
    in ``notes``; a topic left without messages raises :class:`BagContentError`. A message
    whose header stamp is zero (drivers that never fill it) takes the bag's receive time,
    counted per topic in ``notes`` (``energy.json`` ``bench.diagnostics[].notes``).
    """
    from hexapod_common.bags import duplicates_note, iter_messages, open_reader
    from hexapod_common.clocks import ClockCheck, shift_rows
    from hexapod_common.conversions import (
        battery_from_msg,
        joint_state_from_msg,
        point_from_msg,
        stamp_to_s,
        wrench_from_msg,
    )

    bat_samples: list[Any] = []
    frc: list[tuple[float, float]] = []
    tip: list[tuple[float, float]] = []
    ses: list[dict[str, Any]] = []
    dropped: dict[str, list[str]] = {}
    zero_stamps: dict[str, int] = {}
    dups: dict[str, int] = {}   # messages recorded twice (same topic, log time, bytes)

    clocks = ClockCheck()

    def stamped(t_s: float, m: Any) -> float:
        # drivers that leave header.stamp at 0: the bag's receive time stands in
        if t_s != 0.0:
            clocks.observe(m.topic, t_s, 1e-9 * m.stamp_ns)
            return t_s
        if m.stamp_ns != 0:  # stamp 0 at bag time 0: a clock starting at 0, nothing to note
            zero_stamps[m.topic] = zero_stamps.get(m.topic, 0) + 1
        return 1e-9 * m.stamp_ns

    periods: list[float] = []
    duties: list[float] = []
    steps: list[tuple[float, float]] = []   # /gait/phase step length and height [m]
    no_header: dict[str, int] = {}
    joint_rows: list[tuple[float, float, float, float]] = []
    tip_leg: list[str] = [bench_leg] if bench_leg else []
    pause_leg: list[str] = [bench_leg] if bench_leg else []   # whose joints show a pause
    js_names: list[str] = []   # the joint names of a bag read for pauses, for its note
    schedule: list[tuple[float, tuple[str, ...], tuple[bool, ...], tuple[float, ...]]] = []
    gait_rows: list[tuple[float, ...]] = []   # BenchData.gait_rows
    with open_reader(path) as reader:
        reader_notes = list(getattr(reader, 'notes', ()))  # metadata.yaml vs storage, ...
        present = {c.topic for c in reader.connections}
        # a bench without tip motion capture: the tip height from the joint angles
        tip_topic = '/joint_states' if ('/bench/leg_tip' not in present and
                                        '/joint_states' in present) else '/bench/leg_tip'
        needed = tuple(tip_topic if t == '/bench/leg_tip' else t for t in BENCH_TOPICS)
        with_schedule = '/gait/phase' in present
        if session is None:
            if '/bench/session' not in present and set(needed[:3]) <= present:
                raise BagContentError(
                    f'bag {path} has no /bench/session (the sessions\' load and frequency): a '
                    'bench bag of one session, recorded without this project\'s sequencer, is '
                    'given with --bench-sessions CSV (columns bag,load_kg[,frequency_hz])')
            _check_topics(reader, needed, str(path))
            topics: tuple[str, ...] = needed + (('/gait/phase',) if with_schedule else ())
        else:
            _check_topics(reader, needed[:3], str(path))
            if any(c.topic == '/bench/session' and c.msgcount > 0
                   for c in reader.connections):
                raise BagContentError(
                    f'bag {path} records /bench/session and is in the bench sessions file '
                    'too: give it with --bench alone (its own sessions) or drop its '
                    '/bench/session')
            topics = needed[:3] + (('/gait/phase',) if with_schedule else ())
        # split by contact (no /gait/phase), the joints show a leg that stops: a pause (with a
        # motion-capture tip too; not read beside /gait/phase, +30 % reading time)
        joints_apart = (tip_topic != '/joint_states' and '/joint_states' in present and
                        not with_schedule)
        if joints_apart:
            topics += ('/joint_states',)
        for m in iter_messages(reader, topics, duplicates=dups):
            msg = reader.deserialize(m.data, m.msgtype)
            if m.topic == '/joint_states':
                try:
                    js = joint_state_from_msg(msg)
                except ValueError as err:
                    if not joints_apart:
                        dropped.setdefault(m.topic, []).append(str(err))
                    continue
                if joints_apart:
                    js_names.extend(n for n in js.names if n not in js_names)
                    if len(pause_leg) > 1:
                        continue   # several legs' joints and none named: not used
                    try:
                        row = _leg_joint_row(path, js, pause_leg)
                    except BagContentError:
                        pause_leg.extend(('', ''))
                        continue
                else:
                    row = _leg_joint_row(path, js, tip_leg)
                if row is not None:
                    joint_rows.append((stamped(js.t_s, m), *row))
                continue
            if m.topic == '/gait/phase':
                period = float(msg.period)
                periods.append(period if math.isfinite(period) and period > 0 else 0.0)
                duty = float(msg.duty_factor)
                if math.isfinite(duty) and 0 < duty < 1:
                    duties.append(duty)
                geo = (float(msg.step_length), float(msg.step_height))
                if all(math.isfinite(x) and x > 0 for x in geo):
                    steps.append(geo)
                t_gait = stamped(stamp_to_s(msg.header.stamp), m)
                stance_code = tuple(bool(x) for x in msg.in_stance)
                schedule.append((t_gait, tuple(msg.leg_names), stance_code,
                                 _gait_clock(msg)))
                gait_rows.append(_gait_row(t_gait, msg, stance_code))
                continue
            if m.topic == '/battery_state':
                try:
                    b = battery_from_msg(msg)
                except ValueError as err:  # a bad message is dropped, as live
                    dropped.setdefault(m.topic, []).append(str(err))
                    continue
                bat_samples.append(dataclasses.replace(b, t_s=stamped(b.t_s, m)))
            elif m.topic in ('/bench/ground_force', '/bench/leg_tip'):
                if not hasattr(msg, 'header'):   # a std_msgs scalar: receive time, noted
                    no_header[m.topic] = no_header.get(m.topic, 0) + 1
                    msg_t = 1e-9 * m.stamp_ns
                else:
                    msg_t = None
                try:
                    sample = (wrench_from_msg(msg) if m.topic == '/bench/ground_force'
                              else point_from_msg(msg))
                except ValueError as err:
                    raise BagContentError(f'bag {path}: {m.topic} as {m.msgtype}: {err}') \
                        from None
                if msg_t is not None:
                    sample = dataclasses.replace(sample, t_s=msg_t)
                if m.topic == '/bench/ground_force':
                    w = sample
                    row = (stamped(w.t_s, m), float(w.force_n[2]))
                else:
                    p = sample
                    row = (stamped(p.t_s, m), float(p.point_m[2]))
                if not math.isfinite(row[1]):
                    dropped.setdefault(m.topic, []).append(f'non-finite value {row[1]}')
                    continue
                (frc if m.topic == '/bench/ground_force' else tip).append(row)
            else:
                ses.append({
                    't_s': stamped(stamp_to_s(msg.header.stamp), m),
                    'session_id': str(msg.session_id),
                    'state': str(msg.state),
                    'load_kg': float(msg.load_mass),
                    'frequency_hz': float(msg.frequency),
                    'duty_factor': float(msg.duty_factor),
                    'step_length_m': float(msg.step_length),
                    'step_height_m': float(msg.step_height),
                })
        js_legs: list[str] = []   # the legs /joint_states names (the bench leg when one)
        if (tip_topic != '/joint_states' and not tip_leg and '/joint_states' in present
                and any(len(row[1]) > 1 for row in schedule)):
            # a motion-capture tip and a several-leg /gait/phase (the project's gait_scheduler):
            # the bench leg from the joints the driver publishes (its joints file names one leg)
            js_legs = _joint_state_legs(reader, iter_messages, joint_state_from_msg)
            if len(js_legs) == 1:
                tip_leg.append(js_legs[0])
    notes_out: list[str] = []
    if joints_apart and len(pause_leg) != 1:
        joint_rows = []   # several legs' joints: which one is on the bench?
    if joints_apart and js_names and not joint_rows:
        notes_out.append(_unused_joints_note(js_names, bench_leg))
    if tip_topic == '/joint_states':
        tip = _tip_rows_from_joints(joint_rows, leg_dh)
        if tip:
            notes_out.append(
                f'no /bench/leg_tip: the tip height is the forward kinematics of the '
                f'{leg_name} leg (DH table; --leg) on /joint_states {tip_leg[0]}_coxa, '
                '_femur, _tibia (leg base frame)')
    warnings: list[str] = []
    sched = _bench_schedule(schedule, tip_leg, notes_out, warnings,
                            source=('--bench-leg' if bench_leg else
                                    '/joint_states' if tip_leg else ''),
                            js_legs=js_legs)
    shifts, clock_notes = clocks.shifts()   # a topic stamped on another clock
    notes_out.extend(clock_notes)
    if shifts:
        dt = shifts.get
        sched = [(t + dt('/gait/phase', 0.0), v, c) for t, v, c in sched]
        gait_rows = [(r[0] + dt('/gait/phase', 0.0), *r[1:]) for r in gait_rows]
        bat_samples = [dataclasses.replace(b, t_s=b.t_s + dt('/battery_state', 0.0))
                       for b in bat_samples]
        frc = shift_rows(frc, dt('/bench/ground_force', 0.0))
        tip = shift_rows(tip, dt(tip_topic, 0.0))
        joint_rows = [(r[0] + dt('/joint_states', 0.0), *r[1:]) for r in joint_rows]
        for row in ses:
            row['t_s'] += dt('/bench/session', 0.0)
    combined = _prepare_batteries(path, [(b.t_s, k, '/battery_state', b)
                                         for k, b in enumerate(bat_samples)], notes_out)
    bat = [(b.t_s, b.voltage_v, b.current_a) for _, _, _, b in combined]
    if session is not None:
        ses = _session_from_spec(path, session, bat, frc, tip, periods, notes_out,
                                 duties=duties, steps=steps, warnings=warnings,
                                 gait_rows=gait_rows)
    elif ses and bat and frc and tip:
        why = bench_load_problem([(f'/bench/session {s["session_id"]} {s["state"]}',
                                   s['load_kg']) for s in ses])
        if why:
            raise BagContentError(f'bag {path}: {why}')
        ses.sort(key=lambda s: s['t_s'])
        b_rows = np.array(bat, dtype=float).reshape(-1, 3)   # the power, for lost 'cooling's
        b_rows = b_rows[np.argsort(b_rows[:, 0], kind='stable')]
        ses = _repair_sessions(
            ses, tip, min(min(b[0] for b in bat), min(f[0] for f in frc),
                          min(p[0] for p in tip)),
            max(max(b[0] for b in bat), max(f[0] for f in frc), max(p[0] for p in tip)),
            notes_out, warnings,
            power=(b_rows[:, 0], np.abs(b_rows[:, 1] * b_rows[:, 2])))
    for name, rows in (('/battery_state', bat), ('/bench/ground_force', frc),
                       (tip_topic, tip), ('/bench/session', ses)):
        if not rows:
            why = (f' ({len(dropped[name])} dropped, e.g. {dropped[name][0]}' +
                   ('; input power needs both voltage and current)'
                    if name == '/battery_state' else ')')) if name in dropped else ''
            raise BagContentError(f'bag {path}: topic {name} has no usable messages{why}')
    notes = [f'{len(e)} {t} message(s) dropped: {e[0]}' for t, e in sorted(dropped.items())]
    notes += [f'{n} {t} message(s) with a zero header stamp: bag receive time used'
              for t, n in sorted(zero_stamps.items())]
    notes += [f'{t}: {n} message(s) without a header: bag receive time used'
              for t, n in sorted(no_header.items())]
    notes += duplicates_note(dups)
    notes += notes_out
    notes = reader_notes + notes
    b_arr = np.array(sorted(bat))
    f_arr = np.array(sorted(frc))
    t_arr = np.array(sorted(tip))
    ses.sort(key=lambda s: s['t_s'])
    sched.sort(key=lambda r: r[0])
    return BenchData(str(path), b_arr[:, 0], b_arr[:, 1], b_arr[:, 2], f_arr[:, 0],
                     f_arr[:, 1], t_arr[:, 0], t_arr[:, 1], ses, notes,
                     np.array([t for t, _, _ in sched], dtype=float),
                     np.array([v for _, v, _ in sched], dtype=bool),
                     np.array(sorted(gait_rows), dtype=float).reshape(-1, GAIT_COLUMNS),
                     warnings,
                     next((tuple(r[1]) for r in schedule if len(r[1]) > 1), ()),
                     tip_leg[0] if tip_leg else next((r[1][0] for r in schedule
                                                      if len(r[1]) == 1), ''),
                     np.array([c for _, _, c in sched], dtype=float).reshape(-1, 3),
                     *_joint_columns(joint_rows))


def _joint_columns(rows: list[tuple[float, float, float, float]]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:attr:`BenchData.joint_t_s` and :attr:`BenchData.joint_q_rad` of (t, q1, q2, q3) rows,
    in stamp order."""
    arr = np.array(sorted(rows), dtype=float).reshape(-1, 4)
    return arr[:, 0], arr[:, 1:]


def _gait_clock(msg: Any) -> tuple[float, ...]:
    """``(cycle_phase, period, duty_factor, *phase_offsets)`` of a ``/gait/phase`` message
    (NaN for a field it lacks or leaves non-finite; a standing schedule's period is 0)."""
    def num(x: Any) -> float:
        try:
            v = float(x)
        except (TypeError, ValueError):
            return math.nan
        return v if math.isfinite(v) else math.nan

    offsets = getattr(msg, 'phase_offsets', None)
    return (num(getattr(msg, 'cycle_phase', math.nan)), num(getattr(msg, 'period', math.nan)),
            num(getattr(msg, 'duty_factor', math.nan)),
            *(num(x) for x in (offsets if offsets is not None else ())))


def _leg_clock(clock: tuple[float, ...], k: int, legs: int) -> tuple[float, float, float]:
    """Leg ``k``'s phase ``(cycle_phase - theta_k) mod 1``, the period and the duty factor of
    a :func:`_gait_clock` (NaN phase without one offset per leg)."""
    phase, period, duty = clock[:3]
    offsets = clock[3:]
    if len(offsets) != legs or not (math.isfinite(phase) and math.isfinite(offsets[k])):
        return (math.nan, period, duty)
    return ((phase - offsets[k]) % 1.0, period, duty)


def _bench_schedule(rows: list[tuple[float, tuple[str, ...], tuple[bool, ...],
                                     tuple[float, ...]]],
                    tip_leg: list[str], notes: list[str], warnings: list[str], *,
                    source: str = '', js_legs: Sequence[str] = ()
                    ) -> list[tuple[float, bool, tuple[float, float, float]]]:
    """The bench leg's commanded stance from ``/gait/phase`` rows, with its clock (leg phase,
    period, duty factor: :func:`_leg_clock`, which places the phase boundaries between the
    messages: :func:`~hexapod_energy.single_leg.schedule_labels`): its only leg, else the leg
    ``tip_leg`` names (from ``source``: ``--bench-leg`` or ``/joint_states``, noted);
    otherwise none, a warning (the contact split is used: it moved the outside review's
    phase powers by +19..+37 % and -18..-42 %)."""
    out: list[tuple[float, bool, tuple[float, float, float]]] = []
    skipped = 0
    several: tuple[str, ...] = ()
    for t, names, stance, clock in rows:
        if len(stance) != len(names) or not names:
            skipped += 1
            continue
        if len(names) == 1:
            k = 0
        elif tip_leg and tip_leg[0] in names:
            k = names.index(tip_leg[0])
            several = names
        else:
            if source == '--bench-leg':
                raise BagContentError(f'--bench-leg {tip_leg[0]} is not on /gait/phase, '
                                      f'whose legs are {list(names)}')
            why = (f'/joint_states names the leg {tip_leg[0]}, which is not among them'
                   if tip_leg else
                   f'/joint_states names several legs {list(js_legs)}' if len(js_legs) > 1
                   else 'no /joint_states names one leg\'s coxa, femur and tibia')
            warnings.append(
                f'/gait/phase schedules {len(names)} legs {list(names)} and {LEG_UNKNOWN} '
                f'({why}): stance and swing are split by contact, not by the '
                'leg\'s commanded schedule (on an emulated bench that read P_stance +19..+37 '
                '%, P_swing -18..-42 %); give --bench-leg NAME, or record the bench leg\'s '
                'joints alone on /joint_states')
            return []
        out.append((t, stance[k], _leg_clock(clock, k, len(names))))
    if several:
        notes.append(f'bench leg {tip_leg[0]} (from {source or "/joint_states"}) of the '
                     f'{len(several)} legs on /gait/phase: its commanded stance splits the '
                     'phases')
    if skipped:
        notes.append(f'{skipped} /gait/phase message(s) without in_stance for their legs '
                     'left out of the schedule')
    return out


def _joint_state_legs(reader: Any, iter_messages: Any, joint_state_from_msg: Any
                      ) -> list[str]:
    """The legs whose coxa, femur and tibia joints are on ``/joint_states`` (the first message
    that holds any; sorted), read until a message names one (a bench driver's joints file)."""
    for m in iter_messages(reader, ('/joint_states',)):
        try:
            names = list(joint_state_from_msg(reader.deserialize(m.data, m.msgtype)).names)
        except ValueError:
            continue
        legs = _legs_in(names)
        if legs:
            return legs
    return []


def _legs_in(names: Sequence[str]) -> list[str]:
    """Legs with their ``_coxa``, ``_femur`` and ``_tibia`` joints all in ``names``."""
    return sorted({n[:-len('_coxa')] for n in names if n.endswith('_coxa')
                   and f'{n[:-5]}_femur' in names and f'{n[:-5]}_tibia' in names})


def _gait_row(t_s: float, msg: Any, stance: tuple[bool, ...]) -> tuple[float, ...]:
    """One :attr:`BenchData.gait_rows` row of a ``/gait/phase`` message."""
    def num(x: Any) -> float:
        v = float(x)
        return v if math.isfinite(v) else 0.0

    period, length, height = num(msg.period), num(msg.step_length), num(msg.step_height)
    standing = period <= 0 or (length <= 0 and height <= 0)
    code = float(sum(1 << i for i, x in enumerate(stance[:52]) if x))
    return (t_s, 0.0 if standing else 1.0 / period, num(msg.duty_factor), length, height,
            code)


def _unused_joints_note(names: Sequence[str], bench_leg: str | None) -> str:
    """Why a bench bag split by contact did not take its pauses from ``/joint_states``
    (``names``): with the joints a pause mid-swing is seen, with the tip alone it is not (a
    renamed leg read P_stance -10.5 %, P_swing +6.2 % for 1 s at 0.75 Hz, silently)."""
    legs = _legs_in(names)
    shown = ', '.join(list(names)[:6]) + (' ...' if len(names) > 6 else '')
    if len(legs) > 1 and not bench_leg:
        why = f'holds the joints of several legs {legs}: give --bench-leg NAME'
    else:
        want = f'{bench_leg}_coxa' if bench_leg else 'one leg\'s _coxa'
        why = (f'has no {want}, _femur, _tibia ({shown}): name them so with --joint-map')
    return (f'/joint_states {why}; the bench leg\'s pauses are found by its leg tip alone (a '
            'pause mid-swing, the tip held up, is not seen)')


def _leg_joint_row(path: str | Path, js: Any, leg: list[str]
                   ) -> tuple[float, float, float] | None:
    """The bench leg's coxa, femur and tibia angles of one JointState [rad] (None when the
    message does not hold all three, e.g. a joint group published apart). The leg is chosen
    on the first message holding one leg's three joints (kept in ``leg``); several legs'
    joints in one bench bag are refused by name (which one walks on the treadmill?)."""
    names = list(js.names)
    if not leg:
        legs = _legs_in(names)
        if len(legs) > 1:
            raise BagContentError(
                f'bag {path}: no /bench/leg_tip, and /joint_states holds the joints of several '
                f'legs {legs}: a single-leg bench records one leg (or record /bench/leg_tip)')
        if not legs:
            return None
        leg.append(legs[0])
    try:
        idx = [names.index(f'{leg[0]}_{j}') for j in ('coxa', 'femur', 'tibia')]
    except ValueError:
        return None
    if js.position.size != len(names):
        return None
    q = js.position[idx]
    return (float(q[0]), float(q[1]), float(q[2])) if np.all(np.isfinite(q)) else None


def _tip_rows_from_joints(rows: list[tuple[float, float, float, float]], leg_dh: Any
                          ) -> list[tuple[float, float]]:
    """(t, tip z) rows by forward kinematics of the leg from (t, q_coxa, q_femur, q_tibia)."""
    if not rows:
        return []
    from hexapod_gait.kinematics import ANTBOT_LEG, LegKinematics

    arr = np.array(rows, dtype=float)
    z = LegKinematics(leg_dh if leg_dh is not None else ANTBOT_LEG).forward(arr[:, 1:4])[:, 2]
    return [(float(t), float(v)) for t, v in zip(arr[:, 0], z)]


def _session_from_spec(path: str | Path, spec: BenchSessionSpec,
                       bat: list[tuple[float, float, float]], frc: list[tuple[float, float]],
                       tip: list[tuple[float, float]], periods: list[float],
                       notes: list[str], *, duties: Sequence[float] = (),
                       steps: Sequence[tuple[float, float]] = (),
                       warnings: list[str] | None = None,
                       gait_rows: Sequence[tuple[float, ...]] = ()) -> list[dict[str, Any]]:
    """The one walking session of a bag without ``/bench/session`` (see
    :class:`BenchSessionSpec`); its frequency's source goes into ``notes``. The duty factor:
    the spec's, else ``/gait/phase``'s (``duties``), else unknown (0: the phase split then
    takes the measured stance fraction). The step length and height: the spec's, else
    ``/gait/phase``'s (``steps``), else unknown (0: other step geometries are not mapped).

    A walking session is the part of the bag where the leg tip steps (:func:`stepping_span`):
    standing before and after the walk (a recorder started and stopped by hand) is cut off and
    noted (analysed as walking it read P_swing -29 % on the outside review's bench of 2 s +
    10 s + 3 s); pauses without steps inside it are a warning (``warnings``). When the bag's
    ``/gait/phase`` (``gait_rows``, :attr:`BenchData.gait_rows`) stands before (after) its
    walk, that end of the walk is the schedule's (:func:`_schedule_walk_span`): the tip
    cannot tell standing from the last stance under 1.25 ground times, and 0.5-1.5 s of
    standing after the last step was analysed as walking (outside review, A1: P_stance
    -16.7 % at 0.75 Hz with a 1.0 s tail, silently). Without ``/gait/phase`` (split by
    contact) ground time over :data:`EDGE_GROUND` typical ones before the first lift-off
    (after the last touchdown) holds standing: the walk is taken from that lift-off (to that
    touchdown), whole cycles between."""
    if not (bat and frc and tip):
        return []   # the caller names the empty topic
    if spec.frequency_hz is not None:
        freq, source = spec.frequency_hz, 'the sessions file'
    elif periods:
        period = float(np.median(periods))
        freq = 1.0 / period if period > 0 else 0.0
        source = '/gait/phase'
    else:
        t_tip = np.array(sorted(tip))
        freq, source = _tip_frequency_hz(t_tip[:, 0], t_tip[:, 1])
        if not math.isfinite(freq):
            raise BagContentError(
                f'bag {path}: no step frequency: {source}; give frequency_hz in the bench '
                'sessions file')
    t0 = min(min(b[0] for b in bat), min(f[0] for f in frc), min(p[0] for p in tip))
    # the session ends one battery sample after the last one (windows are [start, end))
    t_bat = np.sort(np.array([b[0] for b in bat]))
    step = float(np.median(np.diff(t_bat))) if t_bat.size > 1 else 0.0
    t_end = max(float(t_bat[-1]), max(f[0] for f in frc), max(p[0] for p in tip)) + step
    span = None
    if freq > 0:
        t_tip = np.array(sorted(tip))
        span = stepping_span(t_tip[:, 0], t_tip[:, 1], t0, t_end)
    whole = f'{t_end - t0:.1f} s'
    by_schedule = _schedule_walk_span(gait_rows, t0, t_end) if freq > 0 else None
    if by_schedule is not None:
        start, end = by_schedule
        if span is not None:   # an end the schedule does not cut is the tip's
            start = start if start > t0 else span.start_s
            end = end if end < t_end else span.end_s
        before, after = start - t0, t_end - end
        t0, t_end = start, end
        part = (f'its walking part ({t_end - t0:.1f} s of {whole}, where /gait/phase walks: '
                f'{before:.1f} s before and {after:.1f} s after left out as standing) is one '
                'session')
    elif span is not None and not gait_rows and (
            max(span.lead_s, span.trail_s) > (limit := _edge_ground_limit(span, tip))):
        # split by contact, ground time before the first lift-off (after the last touchdown)
        # longer than a stance holds standing: the walk is taken from that lift-off (to that
        # touchdown), whole cycles between. Cut only beyond 1.25 ground times + 0.1 s, a bag
        # recorded past its last step read P_stance -10 % at 0.75 Hz with a 1.0 s tail and
        # -15 % at 1.5 Hz with 0.5 s, silently
        start = span.first_liftoff_s if span.lead_s > limit else t0
        end = span.last_touchdown_s if span.trail_s > limit else t_end
        before, after = start - t0, t_end - end
        t0, t_end = start, end
        part = (f'its walking part ({t_end - t0:.1f} s of {whole}, where the leg tip steps: '
                f'{before:.1f} s before and {after:.1f} s after left out as standing) is one '
                'session')
    elif span is not None and (span.standing_before_s > 0 or span.standing_after_s > 0):
        t0, t_end = span.start_s, span.end_s
        part = (f'its walking part ({t_end - t0:.1f} s of {whole}, where the leg tip steps: '
                f'{span.standing_before_s:.1f} s before and {span.standing_after_s:.1f} s '
                'after left out as standing) is one session')
    else:
        part = f'the whole bag ({whole}) is one session'
    notes.append(f'no /bench/session: {part}, load {spec.load_kg:g} kg '
                 f'(sessions file), {freq:.4g} Hz (from {source})')
    if span is not None and span.pauses and warnings is not None:
        warnings.append(f'session {Path(path).name} walks at {freq:.4g} Hz but its leg tip '
                        f'makes no step for {span.paused_s:.1f} s in {span.pauses} '
                        'stretch(es): the standing there is analysed as walking (cut the bag '
                        'at the pause)')
    return [{'t_s': t0, 'session_id': Path(path).name, 'state': 'walking',
             'load_kg': spec.load_kg, 'frequency_hz': freq,
             'duty_factor': spec.duty_factor or (float(np.median(duties)) if duties else 0.0),
             'step_length_m': spec.step_length_m or (
                 float(np.median([g[0] for g in steps])) if steps else 0.0),
             'step_height_m': spec.step_height_m or (
                 float(np.median([g[1] for g in steps])) if steps else 0.0)},
            {'t_s': t_end, 'session_id': Path(path).name, 'state': 'end'}]


#: ground time before the first lift-off (after the last touchdown) of a bag split by
#: contact over this many typical ground times (+ 2 leg tip samples) holds standing: a walk
#: cut by the recording has at most a stance there (:func:`_session_from_spec`)
EDGE_GROUND = 1.1


def _edge_ground_limit(span: SteppingSpan, tip: list[tuple[float, float]]) -> float:
    """The longest ground time at a walk's end that is a stance (:data:`EDGE_GROUND`)."""
    t = np.sort(np.array([p[0] for p in tip], dtype=float))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return EDGE_GROUND * span.ground_s + 2.0 * dt


def _schedule_walk_span(gait_rows: Sequence[tuple[float, ...]], t0: float, t1: float
                        ) -> tuple[float, float] | None:
    """The walk of ``[t0, t1)`` by its ``/gait/phase`` rows (:attr:`BenchData.gait_rows`):
    from midway between the last standing row before the first walking row (step frequency
    > 0) and that row, to midway between the last walking row and the standing row after it
    (an end without standing rows is ``t0`` or ``t1``). None when the schedule never stands
    there, or has fewer than 4 rows or no walking row."""
    if len(gait_rows) < 4:
        return None
    g = np.array(sorted(r[:2] for r in gait_rows), dtype=float)
    g = g[(g[:, 0] >= t0) & (g[:, 0] < t1)]
    walking = g[:, 1] > 0 if g.size else np.zeros(0, bool)
    if walking.sum() < 2 or walking.all():
        return None
    k = np.flatnonzero(walking)
    first, last = int(k[0]), int(k[-1])
    start = 0.5 * (g[first - 1, 0] + g[first, 0]) if first > 0 else t0
    end = 0.5 * (g[last, 0] + g[last + 1, 0]) if last + 1 < len(g) else t1
    # a standing label or two where the walk is commanded (a gait node's first message) is
    # no standing to cut: the whole-cycle window holds less than a cycle of it
    start = start if start - t0 >= SCHEDULE_STANDING_MIN_S else t0
    end = end if t1 - end >= SCHEDULE_STANDING_MIN_S else t1
    if start == t0 and end == t1:
        return None
    return float(start), float(end)


#: standing on ``/gait/phase`` shorter than this before (after) its walk is not cut off [s]
SCHEDULE_STANDING_MIN_S = 0.1


#: a leg tip rising above LIFT_FRACTION of its height span (5th to 99th percentile) lifts
#: off, and touches down when it falls below DROP_FRACTION (:func:`_tip_steps`): hysteresis,
#: for a single threshold chattered on the tip's noise at 1 kHz (25 "steps" for 10, median
#: ground time 0 ms: a healthy 0.5 Hz walk read "no step for 48 s"; outside review D, D6).
#: A span under STEP_SPAN_M is no step at all
LIFT_FRACTION = 0.6
DROP_FRACTION = 0.4
STEP_SPAN_M = 0.003
#: ground time before the first (after the last) step beyond this many typical ground times
#: between steps, plus STANDING_SLACK_S, is standing, not the stance of a step
STANDING_GROUND = 1.25
STANDING_SLACK_S = 0.1
#: a pause between two steps inside a walk longer than this many typical ground times (plus
#: STANDING_SLACK_S) is a stretch without steps (warned)
PAUSE_GROUND = 2.5


def _tip_steps(t_s: np.ndarray, z_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lift-off and touchdown stamps [s] of the leg tip's steps (the tip above
    :data:`LIFT_FRACTION` of its height span, until it falls below :data:`DROP_FRACTION`),
    paired: one touchdown after each lift-off. Empty when the span is under
    :data:`STEP_SPAN_M` (a standing leg)."""
    rises, falls, _ = _tip_steps_ends(t_s, z_m)
    return rises, falls


def _tip_steps_ends(t_s: np.ndarray, z_m: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, tuple[bool, bool]]:
    """:func:`_tip_steps`, and whether the tip is lifted at the first and the last sample
    (in a step cut by the span's ends, not standing)."""
    empty = np.zeros(0)
    if z_m.size < 10:
        return empty, empty, (False, False)
    lo, hi = np.percentile(z_m, [5, 99])
    if hi - lo < STEP_SPAN_M:
        return empty, empty, (False, False)
    high = z_m > lo + LIFT_FRACTION * (hi - lo)
    low = z_m < lo + DROP_FRACTION * (hi - lo)
    k = np.arange(z_m.size)
    last = np.maximum.accumulate(np.where(high | low, k, -1))
    if last[-1] < 0:
        return empty, empty, (False, False)
    # between the thresholds the tip keeps its state (the first decisive sample's before it)
    up = high[np.where(last >= 0, last, last[last >= 0][0])].astype(np.int8)
    d = np.diff(up)
    last_low = np.maximum.accumulate(np.where(low, k, 0))
    # the last low sample before a lift-off, the first low one after a touchdown: a span cut
    # from one to the other holds the step whole
    rises, falls = t_s[last_low[:-1][d == 1]], t_s[1:][d == -1]
    if up[0]:
        falls = falls[1:]       # lifted at the start: that step's lift-off is not in the data
    if up[-1]:
        rises = rises[:-1]      # lifted at the end: its touchdown is not in the data
    n = min(rises.size, falls.size)
    return rises[:n], falls[:n], (bool(up[0]), bool(up[-1]))


#: an interval between two leg tip samples shorter than this share of the typical lifted time
#: of a step (lift-off to touchdown, :func:`_tip_steps`) cannot hide a step: the tip is seen
#: in it however sparse the stream (the part above LIFT_FRACTION lasts about 0.8 of it)
HIDDEN_STEP_LIFT_SHARE = 0.5


def _tip_gaps(t_s: np.ndarray, t0: float, t1: float, min_gap_s: float = 0.0) -> np.ndarray:
    """(start, end) rows of the gaps in the sorted tip stamps ``t_s`` of ``[t0, t1)`` (an
    interval over :data:`LABEL_GAP_INTERVALS` times their median and 50 ms, the phase
    split's label gaps, and over ``min_gap_s``), counting the span's ends: time the tip is
    not seen in. ``min_gap_s``: the longest interval in which a step could not hide
    (:data:`HIDDEN_STEP_LIFT_SHARE`): a stream recorded sparser while the leg stands (the
    simulated bench's 2 Hz while cooling) is seen standing when its samples cannot miss a
    step, not unseen for being sparser than the walk's."""
    t = np.concatenate(([t0], t_s, [t1]))
    steps = np.diff(t)
    if t_s.size < 3:
        return np.array([[t0, t1]]) if t1 > t0 else np.zeros((0, 2))
    limit = max(LABEL_GAP_INTERVALS * float(np.median(np.diff(t_s))), 0.05, min_gap_s)
    k = np.flatnonzero(steps > limit)
    return np.column_stack((t[k], t[k + 1]))


#: a ground time between two steps longer than this many typical ground times (plus
#: STANDING_SLACK_S) inside a walk split by contact is a pause: the leg stands, it does not
#: step. Taken as walking, a 1 s pause inside a 6 s walk at 1 Hz read P_stance +4 % and
#: P_swing -21 % (the pause's ground time, 1.6 s, under the PAUSE_GROUND warning's 1.65 s)
PAUSE_SPLIT_GROUND = 1.5


def _tip_pauses(t_s: np.ndarray, z_m: np.ndarray, t0: float, t1: float, frequency_hz: float
                ) -> np.ndarray:
    """(start, end, left-out start, left-out end) rows [s] of the pauses of the walk
    ``[t0, t1)`` at ``frequency_hz`` (whose cycles start at ``t0``, stance first) by its leg
    tip: ground times between two steps longer than :data:`PAUSE_SPLIT_GROUND` typical ones,
    or than a cycle (a walking leg's ground time is shorter: this needs two steps, not three),
    + :data:`STANDING_SLACK_S`, time the tip is not seen in left out. A pause is taken to start
    at the end of the cycle its touchdown ends and to end at the start of the cycle its
    lift-off begins: each edge is placed from its step's detected edge by that edge's median
    offset within the cycle on the walk's other steps. The tip cannot see where in that
    cycle's stance the leg walked on (a pause begun mid-stance goes on from there), so that
    cycle is left out too (the fourth column: the next cycle's start)."""
    m = (t_s >= t0) & (t_s < t1)
    rises, falls = _tip_steps(t_s[m], z_m[m])
    none = np.zeros((0, 4))
    if rises.size < 2 or not frequency_hz > 0:
        return none
    period = 1.0 / frequency_hz
    lift = float(np.median(falls - rises))
    if rises.size < 3 and not lift < period:
        return none
    gaps = _tip_gaps(t_s[m], t0, t1, HIDDEN_STEP_LIFT_SHARE * lift)
    ground = rises[1:] - falls[:-1]
    seen = np.ones(ground.shape, bool)
    for g0, g1 in gaps:
        seen &= ~((falls[:-1] <= g0) & (g1 <= rises[1:]))
    limit = period + STANDING_SLACK_S
    if ground.size >= 2:
        typical = float(np.median(ground[seen] if seen.any() else ground))
        limit = min(limit, PAUSE_SPLIT_GROUND * typical + STANDING_SLACK_S)
    long = seen & (ground > limit)
    if not long.any():
        return none
    k = np.flatnonzero(long)
    # the lift-off's offset in its cycle on the steps before the first pause (a detected
    # lift-off comes a little after mid-cycle), and the lifted time of a step
    r_off = float(np.median((rises[:k[0] + 1] - t0) % period))
    start = falls[k] + (period - r_off - lift)
    end = rises[k + 1] - r_off
    rows = np.column_stack((start, end, start, end + period))
    return rows[rows[:, 1] > rows[:, 0]]


#: a bench leg whose joints (``/joint_states``) all stay within JOINT_STILL_SHARE of the
#: walk's largest joint range (1st to 99th percentile) for JOINT_STILL_CYCLES of its cycles
#: or longer stands still: a pause (:func:`_joint_pauses`). On the simulated AntBot bench
#: (AX-18A, 5 mrad steps) a walking leg's joints move 0.1 rad or more in every quarter
#: cycle at 0.25-3 Hz; 3 % of its 0.78 rad coxa range is 23 mrad
JOINT_STILL_SHARE = 0.03
JOINT_STILL_CYCLES = 0.25
#: joints that move less than this over the whole walk do not show it [rad]
JOINT_WALK_MIN_RAD = 0.05
#: the joints are averaged over this share of the still window (JOINT_STILL_CYCLES) first:
#: the spread of raw samples grows with their noise (white noise of 0.5 deg on the joints hid
#: a 1 s pause mid-swing at 0.75 Hz, P_stance -10.5 %, P_swing +6.2 %, silently)
JOINT_SMOOTH_SHARE = 0.2


def _still_stretches(t_s: np.ndarray, q: np.ndarray, t0: float, t1: float,
                     frequency_hz: float) -> np.ndarray | None:
    """(start, end) rows [s] of the stretches of ``[t0, t1)`` over which every joint of ``q``
    ((n, 3), stamps ``t_s``) stays within :data:`JOINT_STILL_SHARE` of the walk's largest
    joint range for at least :data:`JOINT_STILL_CYCLES` cycles (averaged over
    :data:`JOINT_SMOOTH_SHARE` of that first); time without samples (an interval over 5
    median ones and a third of that) is not still. None when the joints do not show a walk
    (too few samples, or under :data:`JOINT_WALK_MIN_RAD` of motion)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d, uniform_filter1d

    m = (t_s >= t0) & (t_s < t1)
    t, x = t_s[m], q[m]
    if t.size < 20 or not frequency_hz > 0:
        return None
    reach = np.percentile(x, 99, axis=0) - np.percentile(x, 1, axis=0)
    if not float(reach.max()) >= JOINT_WALK_MIN_RAD:
        return None
    dt = float(np.median(np.diff(t)))
    window = JOINT_STILL_CYCLES / frequency_hz
    k = max(3, int(math.ceil(window / dt)) + 1)
    if k > t.size:
        return np.zeros((0, 2))
    # averaged over `smooth` samples, a window of kw of them spans k raw ones: samples
    # i - lo .. i + kw - 1 + hi of the raw stream (a raw still stretch of k samples is still)
    smooth = int(JOINT_SMOOTH_SHARE * k)
    kw, lo, hi = k, 0, 0
    if smooth > 1:
        x = uniform_filter1d(x, smooth, axis=0, mode='nearest')
        kw, lo = max(3, k - smooth + 1), smooth // 2
        hi = k - kw - lo
    spread = (maximum_filter1d(x, kw, axis=0, origin=-(kw // 2)) -
              minimum_filter1d(x, kw, axis=0, origin=-(kw // 2))).max(axis=1)
    # window i holds samples i .. i+kw-1 (the filters' forward window)
    n = t.size - kw + 1
    cs = np.clip(np.arange(n) - lo, 0, t.size - 1)
    ce = np.clip(np.arange(n) + kw - 1 + hi, 0, t.size - 1)
    span = t[ce] - t[cs]
    gap = np.diff(t) > max(5.0 * dt, window / 3.0)
    gaps = np.concatenate(([0], np.cumsum(gap)))
    gapped = gaps[ce] - gaps[cs] > 0
    still = (spread[:n] <= JOINT_STILL_SHARE * float(reach.max())) & ~gapped & \
        (span <= 1.5 * window + 2 * dt)
    if not still.any():
        return np.zeros((0, 2))
    d = np.zeros(t.size + 1, int)
    np.add.at(d, cs[still], 1)
    np.add.at(d, ce[still] + 1, -1)
    cover = np.cumsum(d)[:t.size] > 0
    edge = np.diff(np.concatenate(([0], cover.astype(np.int8), [0])))
    a, b = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1) - 1
    return np.column_stack((t[a], t[b]))


#: a still stretch of the joints between two lift-offs no further apart than a cycle and
#: JOINT_HOLD_SLACK of one (+ 2 leg tip samples) is a hold of the gait, not a pause: a pause
#: stops the gait clock and puts the next lift-off that much later. A leg whose trajectory
#: dwells for 0.3 of every cycle (in its stance or mid-swing) had every cycle taken as a pause
#: and its walking sessions dropped (outside review)
JOINT_HOLD_SLACK = 0.1


def _without_holds(rows: np.ndarray, rises: np.ndarray, period: float, tip_dt: float
                   ) -> np.ndarray:
    """The still stretches ``rows`` ((start, end) [s]) that are not holds of the gait
    (:data:`JOINT_HOLD_SLACK`). A stretch without a lift-off on one side (at the walk's start
    or end), or with another between the same two lift-offs (a hold, then a pause), is a hold
    when the walk has holds and it is no longer than the longest of them (+ the slack)."""
    if not rows.size:
        return rows
    slack = JOINT_HOLD_SLACK * period + 2.0 * tip_dt
    hold = np.zeros(len(rows), bool)
    known = np.zeros(len(rows), bool)
    step = np.searchsorted(rises, rows[:, 0])   # the lift-off interval each stretch is in
    for i, (a, b) in enumerate(rows):
        prev, nxt = rises[rises <= a], rises[rises >= b]
        if prev.size and nxt.size and np.sum(step == step[i]) == 1:
            known[i] = True
            hold[i] = float(nxt[0] - prev[-1]) <= period + slack
    if hold.any():
        longest = float(np.max(rows[hold, 1] - rows[hold, 0]))
        hold |= ~known & (rows[:, 1] - rows[:, 0] <= longest + slack)
    return rows[~hold]


def _joint_pauses(data: BenchData, t0: float, t1: float, frequency_hz: float,
                  duty_factor: float) -> np.ndarray | None:
    """:func:`_tip_pauses` from the bench leg's joints (:attr:`BenchData.joint_t_s`): a pause
    is where the joints stand still (:func:`_still_stretches`) inside the walk, from the
    moment the leg stops to the moment it moves again, with one or two steps around it as
    with many. The rows' last two columns are what the phase split leaves out: from the start
    of the cycle the leg stops in (cycles from ``t0``) to the end of the cycle it walks on in
    (placed by its next lift-off and the lift-offs' median offset in their cycles before the
    first pause, else the duty factor), whole cycles on either side; stretches the gait holds
    every cycle are left in (:func:`_without_holds`). None when the joints cannot tell (none
    recorded, no motion, or still while the tip lifts off: not the bench leg's)."""
    rows = _still_stretches(data.joint_t_s, data.joint_q_rad, t0, t1, frequency_hz)
    if rows is None:
        return None
    m = (data.tip_t_s >= t0) & (data.tip_t_s < t1)
    rises, _ = _tip_steps(data.tip_t_s[m], data.tip_z_m[m])
    if any(np.any((rises > a) & (rises < b)) for a, b in rows):
        return None
    period = 1.0 / frequency_hz
    dt = float(np.median(np.diff(data.joint_t_s))) if data.joint_t_s.size > 1 else 0.0
    # inside the walk: standing that reaches its ends is not a pause inside it
    rows = rows[(rows[:, 0] > t0 + 2 * dt) & (rows[:, 1] < t1 - 2 * dt)]
    tip_dt = float(np.median(np.diff(data.tip_t_s[m]))) if m.sum() > 1 else 0.0
    rows = _without_holds(rows, rises, period, tip_dt)
    if not rows.size:
        return np.zeros((0, 4))
    before = rises[rises < rows[0, 0]]
    r_off = float(np.median((before - t0) % period)) if before.size else \
        (duty_factor if 0 < duty_factor < 1 else 0.5) * period
    tol = 0.05 * period + 2 * dt
    out = []
    grid = t0
    for stop, resume in rows:
        left0 = grid + math.floor((stop - grid) / period) * period
        nxt = rises[rises > resume]
        if nxt.size:
            c = float(nxt[0]) - r_off
            left1 = c + math.ceil((resume - tol - c) / period) * period
        else:
            left1 = t1
        out.append((stop, resume, max(left0, t0), left1))
        grid = left1
    return np.array(out, dtype=float)


def _add_pauses(joints: np.ndarray | None, tip: np.ndarray) -> np.ndarray:
    """The pause rows of :func:`_joint_pauses` (None: the joints cannot tell) with those of
    :func:`_tip_pauses` whose left-out span meets none of theirs, in time order."""
    if joints is None:
        return tip
    apart = [r for r in tip
             if not np.any((joints[:, 2] < r[3]) & (r[2] < joints[:, 3]))]
    rows = np.vstack([joints] + [np.reshape(r, (1, 4)) for r in apart])
    return rows[np.argsort(rows[:, 2], kind='stable')]


@dataclass(frozen=True)
class SteppingSpan:
    """Where the leg tip steps in a session's time span (:func:`stepping_span`)."""

    start_s: float       # the walk's start: the session's, or before the first step
    end_s: float         # the walk's end: the session's, or the last touchdown
    steps: int
    standing_before_s: float   # trimmed from the start (0: kept)
    standing_after_s: float    # trimmed from the end (0: kept)
    pauses: int                # stretches without steps inside the walk
    paused_s: float
    ground_s: float = 0.0      # the typical ground time between steps
    last_touchdown_s: float = math.nan   # where a walk cut after its last step ends
    cycle_s: float = math.nan            # the typical time from one lift-off to the next
    first_liftoff_s: float = math.nan    # where a walk cut before its first step starts
    lead_s: float = 0.0    # ground time before the first lift-off (0: lifted at the start)
    trail_s: float = 0.0   # ground time after the last touchdown (0: lifted at the end)


def stepping_span(t_s: np.ndarray, z_m: np.ndarray, t0: float, t1: float
                  ) -> SteppingSpan | None:
    """The walking part of the span ``[t0, t1)`` from the leg tip's steps (:func:`_tip_steps`):
    ground time before the first step (after the last) longer than :data:`STANDING_GROUND`
    typical ground times between steps (+ :data:`STANDING_SLACK_S`) is standing, cut off:
    the walk then starts at the first lift-off and ends at the last touchdown (the phase
    split takes whole cycles inside: at most a cycle is lost). Pauses
    between steps longer than :data:`PAUSE_GROUND` ground times are counted. None with fewer
    than 3 steps (nothing to compare)."""
    m = (t_s >= t0) & (t_s < t1)
    rises, falls, (up0, up1) = _tip_steps_ends(t_s[m], z_m[m])
    if rises.size < 3:
        return None
    # time without tip samples is not ground time: a marker dropout over a swing read as a
    # pause, or as standing before (after) the walk, a lost message (outside review D, D5)
    gaps = _tip_gaps(t_s[m], t0, t1,
                     HIDDEN_STEP_LIFT_SHARE * float(np.median(falls - rises)))
    ground = rises[1:] - falls[:-1]
    seen = np.ones(ground.shape, bool)
    for g0, g1 in gaps:
        seen &= ~((falls[:-1] <= g0) & (g1 <= rises[1:]))
    typical = float(np.median(ground[seen] if seen.any() else ground))
    limit = STANDING_GROUND * typical + STANDING_SLACK_S
    before = gaps[:, 1][gaps[:, 1] <= rises[0]]
    after = gaps[:, 0][gaps[:, 0] >= falls[-1]]
    # a tip lifted at the span's start (end) is in a step cut there, not standing: a walk
    # that runs a latency late is cut by its 'cooling' in the swing (outside review D, D4)
    lead = 0.0 if up0 else float(rises[0] - (before.max() if before.size else t0))
    trail = 0.0 if up1 else float((after.min() if after.size else t1) - falls[-1])
    start = float(rises[0]) if lead > limit else t0
    # just after the last touchdown's sample (spans are [start, end))
    dt = float(np.median(np.diff(t_s[m])))
    last = min(t1, float(falls[-1]) + 0.5 * dt)
    end = last if trail > limit else t1
    long = seen & (ground > PAUSE_GROUND * typical + STANDING_SLACK_S)
    return SteppingSpan(start, end, int(rises.size), start - t0, t1 - end, int(long.sum()),
                        float(np.sum(ground[long])), typical, last,
                        float(np.median(np.diff(rises))), float(rises[0]), lead, trail)


#: bench data longer than this before the first ``/bench/session`` message is warned about
#: (it is in no session: a recorder that missed the sequencer's latched first messages)
UNSESSIONED_LEAD_S = 2.0
#: a leg that starts stepping up to this long after its session's 'walking' message has a
#: start latency (a sequencer that does not wait for the gait node; the analysis skips its
#: first settle_s = 1 s anyway): noted, not warned as a lost message (outside review D, D4)
START_LATENCY_S = 1.0
#: a session of only 'done' messages followed by less than this much data [s] is the plan's
#: end marker (noted, not warned)
DONE_MARKER_S = 1.0
#: a walking session this much longer or shorter than the median walk is noted
WALK_LENGTH_SPREAD = 0.25


#: a walk whose leg tip is not seen stepping after its last touchdown for this many of its
#: cycles (and the standing limit) ends there when its power is at the bench's cooling level
#: from a cycle after that touchdown on (:func:`_power_stop`)
POWER_STOP_CYCLES = 3.0
#: ... in at least this share of the power samples there
POWER_STOP_SHARE = 0.9
#: ... against the power of the walk's cycles (lift-off to lift-off) no longer than this many
#: typical cycles (a cycle holding a pause, or the standing of a late start, is left out)
POWER_STOP_CYCLE_SLACK = 1.5


def _cooling_power(ses: list[dict[str, Any]], t_end_s: float, t_p: np.ndarray,
                   p_w: np.ndarray) -> dict[float, list[tuple[float, float]]]:
    """The power [W] of each labelled 'cooling' stretch of the stamp-ordered ``ses`` (from its
    message to the next message, at least 3 samples): (median, robust standard deviation),
    by load [kg]. ``t_p``: the power's stamps [s], sorted."""
    out: dict[float, list[tuple[float, float]]] = {}
    for k, s in enumerate(ses):
        if s['state'] != 'cooling':
            continue
        end = ses[k + 1]['t_s'] if k + 1 < len(ses) else t_end_s
        x = p_w[np.searchsorted(t_p, s['t_s']):np.searchsorted(t_p, end)]
        if x.size >= 3:
            mid = float(np.median(x))
            out.setdefault(round(float(s['load_kg']), 6), []).append(
                (mid, robust_sigma(x, mid)))
    return out


def _power_stop(t_p: np.ndarray, p_w: np.ndarray,
                cooling: dict[float, list[tuple[float, float]]], load_kg: float,
                lift_offs: np.ndarray, last_s: float, t1: float, cycle_s: float
                ) -> tuple[bool | None, str]:
    """Whether the walk stops at its last touchdown ``last_s`` by its power, and why: True
    when, from a cycle after it to ``t1`` on, :data:`POWER_STOP_SHARE` of the power samples
    are nearer the bench's cooling level (the highest labelled cooling stretch's median power,
    of the same load when the bench cools at it) than the lowest the walk drew while stepping
    (the 5th percentile over its whole cycles, lift-off to lift-off ``lift_offs``, no longer
    than :data:`POWER_STOP_CYCLE_SLACK` typical cycles ``cycle_s``: a start latency or a pause
    inside the walk draws the standing power), which must stand out from that level by 3 of
    its robust standard deviations; False when the power stays nearer the walk's; None when
    the power cannot tell (no labelled cooling, too few samples, or a walk that draws no more
    than the bench cools at). Physical evidence that outlives a lost 'cooling' message: a
    bench powered off (the simulated one), or holding still, draws less than any phase of a
    walk."""
    bands = cooling.get(round(float(load_kg), 6)) or [b for v in cooling.values() for b in v]
    if not bands:
        return None, 'no labelled \'cooling\' stretch to compare with'
    if not (cycle_s > 0) or lift_offs.size < 2:
        return None, 'no whole cycle'
    r0, r1 = lift_offs[:-1], lift_offs[1:]
    whole = (r1 - r0) <= POWER_STOP_CYCLE_SLACK * cycle_s
    k = np.searchsorted(lift_offs, t_p, side='right') - 1
    inside = (k >= 0) & (k < r0.size)
    stepping = np.zeros(t_p.shape, bool)
    stepping[inside] = whole[k[inside]]
    walk = p_w[stepping & (t_p < last_s)]
    tail = p_w[(t_p >= last_s + cycle_s) & (t_p < t1)]
    if walk.size < 10 or tail.size < 3:
        return None, f'{walk.size} power samples in its whole cycles, {tail.size} after them'
    hi = max(m for m, _ in bands)
    sigma = float(np.median([sd for _, sd in bands]))
    low = float(np.percentile(walk, 5))
    if low <= hi + 3.0 * sigma:
        return None, (f'the walk\'s lowest {low:.2f} W is not above the bench\'s cooling '
                      f'{hi:.2f} W')
    why = (f'median {np.median(tail):.2f} W, the bench\'s cooling {hi:.2f} W, the walk\'s '
           f'lowest {low:.2f} W')
    return float(np.mean(tail < 0.5 * (hi + low))) >= POWER_STOP_SHARE, why


def _repair_sessions(ses: list[dict[str, Any]], tip: list[tuple[float, float]],
                     t_first_s: float, t_end_s: float, notes: list[str],
                     warnings: list[str],
                     power: tuple[np.ndarray, np.ndarray] | None = None
                     ) -> list[dict[str, Any]]:
    """``/bench/session`` messages checked against the leg tip's steps
    (:func:`stepping_span`), for a lost message must not silently drop or corrupt a session
    (outside review: a lost 'cooling' ran a 1 Hz walk into 3 s of standing, P_swing -25 %; a
    lost 'walking' dropped a session with 10 s of data; a missed latched first message dropped
    the 0 Hz session of the first load, all without a word).

    * A walking session whose tip makes no step over its end (start) beyond the typical
      ground time is ended (started) where stepping stops (starts): a 'cooling' ('walking')
      message is put there; warned. A tip not seen after its last step (a stream recorded
      too sparsely there to show a step) ends the walk at that step when the power
      (``power``: sorted stamps [s], watts) has dropped to the bench's cooling level for
      :data:`POWER_STOP_CYCLES` cycles (:func:`_power_stop`; outside review: a lost 'cooling'
      on the simulated bench, recorded at 2 Hz while cooling, ran a 2 Hz walk 120 s into
      the cooling, P_stance +30 %, P_swing -11 %, no warning).
    * A session that never reports 'walking' but whose tip steps at its frequency gets its
      walk back from the steps; without steps (a 0 Hz session) it is left out; warned.
    * Data before the first message (over :data:`UNSESSIONED_LEAD_S`) is in no session;
      warned. Pauses without steps inside a walk are warned; walks whose length differs from
      the median by over :data:`WALK_LENGTH_SPREAD` are noted.

    ``ses`` is stamp-ordered; returns the (possibly) amended, stamp-ordered list."""
    if not ses:
        return ses
    arr = np.array(sorted(tip), dtype=float).reshape(-1, 2)
    t_tip, z_tip = arr[:, 0], arr[:, 1]
    out = [dict(s) for s in ses]
    t_p, p_w = power if power is not None else (np.zeros(0), np.zeros(0))
    cooling = _cooling_power(ses, t_end_s, t_p, p_w)

    def steps_in(t0: float, t1: float) -> int:
        m = (t_tip >= t0) & (t_tip < t1)
        return int(_tip_steps(t_tip[m], z_tip[m])[0].size)

    lead = out[0]['t_s'] - t_first_s
    if lead > UNSESSIONED_LEAD_S:
        n = steps_in(t_first_s, out[0]['t_s'])
        warnings.append(
            f'{lead:.1f} s of bench data before the first /bench/session message (session '
            f'{out[0]["session_id"]} {out[0]["state"]}) are in no session ({n} leg tip steps '
            'there): left out. A recorder started after the sequencer misses its first, '
            'latched messages (record /bench/session with transient-local durability, or '
            'start the recorder first); a lost first session is missing from the results')
    # sessions that never report 'walking': their walk back from the tip's steps
    ids = list(dict.fromkeys(s['session_id'] for s in out))
    walked = {s['session_id'] for s in out if s['state'] == 'walking'}
    for sid in ids:
        if sid in walked:
            continue
        k = [i for i, s in enumerate(out) if s['session_id'] == sid]
        t0 = out[k[0]]['t_s']
        t1 = next((s['t_s'] for s in out[k[-1] + 1:]), t_end_s)
        freq = max(float(out[i].get('frequency_hz') or 0.0) for i in k)
        states = ', '.join(dict.fromkeys(out[i]['state'] for i in k))
        length = max(t1 - t0, 0.0)   # a marker after the data's end: 0 s (it read "-0.0 s")
        if all(out[i]['state'] == 'done' for i in k) and length < DONE_MARKER_S:
            # the plan's end-of-plan marker under its own id: nothing was to walk (outside
            # review C4: a warning for a benign marker)
            notes.append(f'session {sid}: only the end-of-plan marker \'done\' '
                         f'({length:.1f} s of data after it): nothing to analyse')
            continue
        span = stepping_span(t_tip, z_tip, t0, t1) if freq > 0 else None
        if span is None or span.steps < 3 or span.end_s - span.start_s < 2.0 / freq:
            warnings.append(
                f'session {sid} never reports state walking (only {states}; a lost '
                f'/bench/session message?) and its leg tip ' +
                ('does not step' if freq > 0 else 'cannot show a 0 Hz walk') +
                f': its {length:.1f} s of data are left out')
            continue
        base = max(k, key=lambda i: float(out[i].get('frequency_hz') or 0.0))
        out.append(dict(out[base], t_s=span.start_s, state='walking'))
        out.append(dict(out[base], t_s=span.end_s, state='cooling'))
        warnings.append(
            f'session {sid} never reports state walking (only {states}; a lost /bench/session '
            f'message?): its walk taken where its leg tip steps at {freq:.4g} Hz '
            f'({span.end_s - span.start_s:.1f} s, {span.steps} steps)')
    out.sort(key=lambda s: s['t_s'])
    # walks that run into standing (a lost 'cooling') or start before the steps
    lengths: list[tuple[str, float]] = []
    latencies: list[tuple[str, float]] = []
    for s, t0, t1 in _walking_segments(out, t_end_s):
        if not float(s.get('frequency_hz') or 0.0) > 0:
            continue
        span = stepping_span(t_tip, z_tip, t0, t1)
        if span is None:
            lengths.append((s['session_id'], t1 - t0))
            continue
        stop = unsure = None
        limit = STANDING_GROUND * span.ground_s + STANDING_SLACK_S
        if span.standing_after_s == 0 and \
                t1 - span.last_touchdown_s > max(limit, POWER_STOP_CYCLES * span.cycle_s):
            m = (t_tip >= t0) & (t_tip < t1)
            lift_offs = _tip_steps_ends(t_tip[m], z_tip[m])[0]
            stopped, why = _power_stop(t_p, p_w, cooling, float(s.get('load_kg') or 0.0),
                                       lift_offs, span.last_touchdown_s, t1, span.cycle_s)
            if stopped:
                stop = why
                span = dataclasses.replace(span, end_s=span.last_touchdown_s,
                                           standing_after_s=t1 - span.last_touchdown_s)
            elif stopped is None:
                unsure = why
        if span.standing_before_s > 0:
            # the walk's first message moves to the first step (same session, same values)
            for x in out:
                if x['session_id'] == s['session_id'] and x['state'] == 'walking' and \
                        t0 <= x['t_s'] < span.start_s:
                    x['t_s'] = span.start_s
        if span.standing_after_s > 0:
            # a sequencer that repeats its state would start the walk again after the stop
            out = [x for x in out if not (x['session_id'] == s['session_id'] and
                                          x['state'] == 'walking' and
                                          span.end_s <= x['t_s'] < t1)]
            out.append(dict(s, t_s=span.end_s, state='cooling'))
        # the first lift-off comes a ground time after the walk's start (stance first)
        delay = span.standing_before_s - span.ground_s
        late = span.standing_before_s > 0 and delay <= START_LATENCY_S
        if late:
            latencies.append((s['session_id'], max(delay, 0.0)))
        before = 0.0 if late else span.standing_before_s
        if before > 0:
            warnings.append(
                f'session {s["session_id"]}: its leg tip starts stepping about {delay:.1f} s '
                f'after its \'walking\' message (a walk started late, or a lost /bench/session '
                f'message?): the walk is taken from its first step '
                f'({span.end_s - span.start_s:.1f} s of {t1 - t0:.1f} s)')
        if stop is not None:
            warnings.append(
                f'session {s["session_id"]}: its leg tip is not seen stepping in the last '
                f'{span.standing_after_s:.1f} s of its {t1 - t0:.1f} s in state walking, and '
                f'its power is at the bench\'s cooling level there ({stop}; a lost '
                f'/bench/session \'cooling\'?): the walk is taken to its last step, '
                f'{span.end_s - t0:.1f} s after its \'walking\' message '
                f'({span.end_s - span.start_s:.1f} s)')
        elif unsure is not None:
            warnings.append(
                f'session {s["session_id"]}: its leg tip is not seen after its last step, in '
                f'the last {t1 - span.last_touchdown_s:.1f} s of its {t1 - t0:.1f} s in state '
                f'walking, and its power cannot tell whether it walked on ({unsure}): '
                f'analysed as walking to its next /bench/session message; a lost \'cooling\' '
                f'would put standing in its phase powers (record /bench/leg_tip while the '
                f'leg stands as often as while it walks)')
        elif span.standing_after_s > 0:
            warnings.append(
                f'session {s["session_id"]}: its leg tip makes no step in the last '
                f'{span.standing_after_s:.1f} s of its {t1 - t0:.1f} s in state walking (a '
                f'lost /bench/session message?): the walk is taken where it steps '
                f'({span.end_s - span.start_s:.1f} s)')
        if span.pauses:
            warnings.append(
                f'session {s["session_id"]}: its leg tip makes no step for '
                f'{span.paused_s:.1f} s in {span.pauses} stretch(es) inside its walk: the '
                'standing there is analysed as walking')
        lengths.append((s['session_id'], span.end_s - span.start_s))
        out.sort(key=lambda x: x['t_s'])
    if latencies:
        d = [x for _, x in latencies]
        notes.append(f'{len(latencies)} walking session(s) start stepping about {min(d):.2f} '
                     f'to {max(d):.2f} s after their \'walking\' message (a start latency, up '
                     f'to {START_LATENCY_S:g} s taken as one): each walk is taken from its '
                     'first step: ' +
                     ', '.join(f'{sid} {x:.2f} s' for sid, x in latencies[:5]) +
                     (' ...' if len(latencies) > 5 else ''))
    if len(lengths) >= 3:
        mid = float(np.median([d for _, d in lengths]))
        odd = [(sid, d) for sid, d in lengths if abs(d - mid) > WALK_LENGTH_SPREAD * mid]
        if odd:
            notes.append(f'{len(odd)} walking session(s) of another length than the median '
                         f'{mid:.1f} s: ' + ', '.join(f'{sid} {d:.1f} s' for sid, d in odd[:5]) +
                         (' ...' if len(odd) > 5 else ''))
    return out


def merge_bench_data(datas: Sequence[BenchData], reasons: list[str] | None = None
                     ) -> BenchData | None:
    """One-session bench bags (``--bench-sessions``) as one bench: their streams and sessions
    in time order, so that the force clock offset and the force sign are estimated over every
    session together (as for a bag that records them all). None when two bags overlap in time
    by more than a sample step (plus the stamps' jitter) of the earlier one's
    ``/battery_state`` (their clocks cannot be one bench's): the bags are then analysed one by
    one, and ``reasons`` gets why. Bags
    recorded back to back (a recorder splitting at the sessions' boundaries) overlap by up to
    a step: a session ended at its last stamp plus a step, 0.3 ms after the next bag's first
    stamp, and every bag was analysed alone (its own force offset, and a "force sign not
    checked" on each 0 Hz bag)."""
    if not datas:
        return None

    # the battery (power) stream's span: the force stream's clock offset is what the merged
    # analysis estimates, and a 0.05 s one read as "not one bench's recording" (outside
    # review D, D7)
    def first(d: BenchData) -> float:
        return float(d.battery_t_s[0]) if d.battery_t_s.size else math.inf

    def last(d: BenchData) -> float:
        return float(d.battery_t_s[-1]) if d.battery_t_s.size else -math.inf

    def step(d: BenchData) -> float:
        """A step of the battery stamps plus their jitter (3 robust sigmas of the steps): 3 ms
        of jitter at 200 Hz overlapped back-to-back bags by 4.8 ms."""
        t = d.battery_t_s
        if t.size < 2:
            return 0.0
        dt = np.diff(t)
        mid = float(np.median(dt))
        return mid + 3.0 * robust_sigma(dt, mid)

    order = sorted(range(len(datas)), key=lambda i: first(datas[i]))
    for i, j in zip(order, order[1:]):
        a, b = datas[i], datas[j]
        overlap = last(a) - first(b)
        if overlap > step(a):
            if reasons is not None:
                reasons.append(
                    f'{Path(a.path).name} (battery to {last(a):.3f} s) and {Path(b.path).name} '
                    f'(from {first(b):.3f} s) overlap by {overlap:.3g} s: not one bench\'s '
                    'recording')
            return None

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(datas[i], name) for i in order])

    def by_time(t: np.ndarray, *cols: np.ndarray) -> list[np.ndarray]:
        k = np.argsort(t, kind='stable')   # back to back within a step: in stamp order
        return [t[k], *(c[k] for c in cols)]

    def by_time_rows(rows: np.ndarray) -> np.ndarray:
        return rows[np.argsort(rows[:, 0], kind='stable')] if rows.size else rows

    bt, bv, ba = by_time(cat('battery_t_s'), cat('battery_v'), cat('battery_a'))
    ft, fz = by_time(cat('force_t_s'), cat('force_z_n'))
    tt, tz = by_time(cat('tip_t_s'), cat('tip_z_m'))
    def clock(d: BenchData) -> np.ndarray:   # a schedule replaced without its clock: none
        n = d.schedule_t_s.size
        return d.schedule_clock if d.schedule_clock.shape == (n, 3) else np.full((n, 3), np.nan)

    st, ss, sc = by_time(cat('schedule_t_s'), cat('schedule_stance'),
                         np.concatenate([clock(datas[i]) for i in order]).reshape(-1, 3))
    sessions = []
    for n, i in enumerate(order):
        nd = datas[order[n + 1]] if n + 1 < len(order) else None
        nxt = math.inf if nd is None else min(
            [first(nd)] + [float(x['t_s']) for x in nd.sessions[:1]])
        # a session's end (its last stamp plus a step) no later than the next bag's start
        sessions += [dict(s, t_s=min(s['t_s'], nxt)) if s['state'] != 'walking' else s
                     for s in datas[i].sessions]
    notes = [f'{Path(datas[i].path).name}: {n}' for i in order for n in datas[i].notes]
    return BenchData(', '.join(datas[i].path for i in order), bt, bv, ba, ft, fz, tt, tz,
                     sessions, notes, st, ss, by_time_rows(cat('gait_rows')),
                     [f'{Path(datas[i].path).name}: {w}' for i in order
                      for w in datas[i].warnings],
                     next((d.schedule_legs for d in datas if d.schedule_legs), ()),
                     next((d.bench_leg for d in datas if d.bench_leg), ''), sc,
                     *by_time(cat('joint_t_s'), np.concatenate(
                         [datas[i].joint_q_rad for i in order]).reshape(-1, 3)))


def _walking_segments(sessions: list[dict[str, Any]], t_end_s: float
                      ) -> list[tuple[dict[str, Any], float, float]]:
    """Contiguous (session, start, end) intervals in state 'walking'."""
    out: list[tuple[dict[str, Any], float, float]] = []
    current: dict[str, Any] | None = None
    start = 0.0
    def params(x: dict[str, Any]) -> tuple[Any, ...]:
        return tuple(x.get(k) for k in ('load_kg', 'frequency_hz', 'duty_factor'))

    for s in sessions + [{'t_s': t_end_s, 'session_id': None, 'state': 'end'}]:
        # a new load, frequency or duty factor under the same id is a new session too (a lab
        # that names its sessions by load: 42 sessions read as 7 of 48 s, each labelled with
        # its first frequency)
        same = current is not None and s['session_id'] == current['session_id'] and \
            s['state'] == 'walking' and params(s) == params(current)
        if same:
            continue
        if current is not None:
            out.append((current, start, s['t_s']))
            current = None
        if s['state'] == 'walking':
            current, start = s, s['t_s']
    return out


#: a bench session's /gait/phase covers it when it holds at least this share of a label per
#: :data:`SCHEDULE_LABEL_S` over the session ...
SCHEDULE_MIN_SHARE = 0.8
SCHEDULE_LABEL_S = 0.02
#: ... and no gap longer than this [s] between labels (or the session's ends)
SCHEDULE_MAX_GAP_S = 0.1


def schedule_coverage(t_s: np.ndarray, t0: float, t1: float) -> str:
    """Why the ``/gait/phase`` labels stamped ``t_s`` (sorted, inside ``[t0, t1)``) do not
    cover a bench session ('' when they do): fewer than :data:`SCHEDULE_MIN_SHARE` of one per
    :data:`SCHEDULE_LABEL_S` (and 4), or a gap over :data:`SCHEDULE_MAX_GAP_S`. A label per
    20 ms counted exactly failed a 50 Hz bench gait node by one sample in 24 sessions of 30,
    which then took the contact split under a note saying they had no /gait/phase (another
    review)."""
    span = t1 - t0
    if not t_s.size:
        return 'no /gait/phase there'
    need = max(4.0, SCHEDULE_MIN_SHARE * span / SCHEDULE_LABEL_S)
    if t_s.size < need:
        return (f'/gait/phase too sparse: {t_s.size} label(s) over {span:.2f} s, fewer than '
                f'{SCHEDULE_MIN_SHARE * 100:.0f} % of one per {1e3 * SCHEDULE_LABEL_S:.0f} ms')
    gap = float(np.max(np.diff(np.concatenate(([t0], np.sort(t_s), [t1])))))
    if gap > SCHEDULE_MAX_GAP_S:
        return f'/gait/phase silent for {gap:.3f} s (over {SCHEDULE_MAX_GAP_S:g} s)'
    return ''


def _coverage_reasons(reasons: list[str]) -> str:
    """The reasons of :func:`schedule_coverage`, counted by kind."""
    kinds: dict[str, list[str]] = {}
    for r in reasons:
        kinds.setdefault(r.split(':')[0], []).append(r)
    return '; '.join(f'{len(v)} session(s): {v[0]}' + (' ...' if len(v) > 1 and
                                                     v[0] != v[-1] else '')
                     for v in kinds.values()) or 'no /gait/phase there'


def bench_phase_samples(
    data: BenchData,
    *,
    current_sign: str = 'auto',
    settle_s: float = 1.0,
    force_threshold_n: float | None = None,
    height_margin_m: float = 0.01,
    force_sign: str = 'auto',
    phase_split: str = 'auto',
) -> tuple[list[PhaseSample], dict[str, Any]]:
    """Per-session phase powers of one bench bag, and diagnostics.

    ``phase_split``: which samples are stance. ``contact`` is Brodoline et al.'s: the normal
    force above a threshold and the tip low (:func:`stance_mask`). ``schedule`` takes the
    commanded stance of the bench leg from ``/gait/phase`` (each boundary between two labels
    where the messages' clock puts it: :attr:`BenchData.schedule_clock`,
    :func:`~hexapod_energy.single_leg.schedule_labels`), the timeline Eq. 1 composes the
    phases on (the robot's ``L(t)`` is its commanded schedule too); ``auto`` (default) takes
    the schedule for every session it covers, else the contact. The sensed contact lasts
    longer than the commanded stance (the stage rides on the tip until it is lifted off its
    stop, the servos lag): with the contact split the surfaces carry part of the swing's cost
    as stance cost, which Eq. 1 then scales with the wrong phase. Simulated AntBot bench
    (5 loads x 0-3 Hz) against simulated robots: prediction errors with the contact split
    +22 % (wave, 8 legs, 0.1 m/s), +25 % (wave, 6 legs), +13 % (tetrapod, ripple), +8 %
    (tripod 0.3 m/s); with the schedule +6 %, +8 %, +5 to +7 %, +5 %.

    The force stream is shifted by the median over walking sessions, weighted by each session's
    number of cycles, of the cross-correlation offset, each session's peak taken nearest the
    peak of all sessions' correlations together (:func:`_force_offset_s`); the first
    ``settle_s`` of each walking segment is skipped.

    ``force_sign``: the contract's ``force.z`` is the treadmill's normal force, positive in
    compression; many load cells report compression negative. ``positive`` takes the force as
    recorded, ``negative`` negates it, ``auto`` (default) decides from the data
    (:func:`force_sign_factor`) and notes a flip in ``diag['notes']``.

    ``diag['warnings']``: what ``energy`` puts in its top-level warnings: a several-leg
    ``/gait/phase`` whose bench leg is unknown (the contact split instead; not with
    ``phase_split='contact'``), and each session labelled with another frequency than its
    ``/gait/phase`` walked (analysed at the walked one: :func:`_walked_segments`).
    """
    from hexapod_energy.descriptors import resolve_current_sign

    if phase_split not in PHASE_SPLITS:
        raise ValueError(f'phase split must be one of {PHASE_SPLITS}, got {phase_split!r}')
    if phase_split == 'schedule' and not data.schedule_t_s.size:
        raise BagContentError(f'bag {data.path}: phase split schedule needs the bench leg\'s '
                              '/gait/phase (in_stance; of several legs: --bench-leg NAME); use '
                              'the contact split')
    sign = resolve_current_sign(data.battery_v, data.battery_a, current_sign)
    power = sign * data.battery_v * data.battery_a
    t_end = float(max(data.battery_t_s[-1], data.force_t_s[-1], data.tip_t_s[-1]))
    segments = _walking_segments(data.sessions, t_end)
    if not segments:
        raise BagContentError(f'bag {data.path}: /bench/session never reports state walking')
    notes = list(data.notes)
    warnings = list(data.warnings)
    if phase_split == 'contact':   # asked for: the bench leg's schedule is not needed
        notes += [w for w in warnings if LEG_UNKNOWN in w]
        warnings = [w for w in warnings if LEG_UNKNOWN not in w]
    segments = _walked_segments(data, segments, warnings)
    tip_span = float(np.subtract(*np.nanpercentile(data.tip_z_m, [95, 5]))) \
        if data.tip_z_m.size else 0.0
    if tip_span > 1.0:
        raise BagContentError(
            f'bag {data.path}: /bench/leg_tip z spans {tip_span:.1f} between its 5th and 95th '
            'percentiles, far beyond a leg\'s stroke: the positions look like millimetres '
            '(the contract is metres, REP-103)')
    walk_tip = np.zeros(data.tip_t_s.shape, bool)
    for s, t0, t1 in segments:
        if s['frequency_hz'] > 0:
            walk_tip |= (data.tip_t_s >= t0) & (data.tip_t_s < t1)
    if walk_tip.sum() >= 20 and not data.schedule_t_s.size:
        span = float(np.subtract(*np.nanpercentile(data.tip_z_m[walk_tip], [95, 5])))
        if span < FLAT_TIP_M:
            raise BagContentError(
                f'bag {data.path}: the leg tip\'s height spans {1e3 * span:.1f} mm over the '
                'walking sessions: it is not the height (a y-up motion-capture frame? the '
                'contract\'s z is up, REP-103), so stance and swing cannot be split by it')
    f_sign, why = force_sign_factor(data, segments, force_sign)
    if why:
        notes.append(why)
    if f_sign < 0:
        data = dataclasses.replace(data, force_z_n=-data.force_z_n)
    offset = _force_offset_s(data, segments, notes, warnings)
    samples = []
    labelled: list[tuple[dict[str, Any], float, float, np.ndarray, np.ndarray, float,
                         float | None, np.ndarray | None]] = []
    # the schedule's clock places each phase boundary between its labels (schedule split);
    # a schedule replaced without it (one row per label) takes the nearest label
    clock = data.schedule_clock if data.schedule_clock.shape == (data.schedule_t_s.size, 3) \
        else None
    splits: dict[str, int] = {}
    guessed: list[float] = []
    force_gaps: set[str] = set()
    label_gaps: set[str] = set()
    uncovered: list[str] = []   # why the schedule did not cover a walking session
    paused: dict[str, np.ndarray] = {}   # pauses left out of the phase split
    agreement: dict[str, list[float]] = {}   # per leg: each cycle's schedule-contact agreement
    for s, t0, t1 in segments:
        a = t0 + settle_s if t1 - t0 > 2 * settle_s else t0
        f = s['frequency_hz']
        if f > 0 and (t1 - t0) * f >= 1.0:
            # whole gait cycles only (the walk starts at cycle phase 0 when the session enters
            # 'walking'): a fractional cycle weights one phase more than the other
            # Session stamps a few ms off (receive times standing in for zero stamps, clock
            # jitter) must not drop a whole cycle: within CYCLE_TOLERANCE of a cycle the
            # count is rounded up and the window clipped at the session's end
            a = t0 + math.ceil((a - t0) * f - CYCLE_TOLERANCE) / f
            if t1 - a < (1.0 - CYCLE_TOLERANCE) / f:
                a = t0
            t1 = min(t1, a + math.floor((t1 - a) * f + CYCLE_TOLERANCE) / f)
        pm = (data.battery_t_s >= a) & (data.battery_t_s < t1)
        tm = (data.tip_t_s >= a) & (data.tip_t_s < t1)
        if not pm.any() and s['frequency_hz'] <= 0:
            continue
        t_tip = data.tip_t_s[tm]
        sm = (data.schedule_t_s >= a) & (data.schedule_t_s < t1)
        why_not = schedule_coverage(data.schedule_t_s[sm], a, t1)
        covered = not why_not and phase_split != 'contact'
        if why_not and s['frequency_hz'] > 0 and phase_split != 'contact':
            uncovered.append(why_not)
        label_clock = None
        by_contact = False
        if s['frequency_hz'] > 0 and covered:
            t_tip, st = data.schedule_t_s[sm], data.schedule_stance[sm]
            label_clock = clock[sm] if clock is not None else None
            splits['schedule'] = splits.get('schedule', 0) + 1
            _schedule_contact_cycles(data, offset, a, t1, s['frequency_hz'], t_tip, st,
                                     agreement, force_threshold_n=force_threshold_n,
                                     height_margin_m=height_margin_m)
        elif s['frequency_hz'] > 0 and len(t_tip) >= 4:
            ft = data.force_t_s + offset
            fz = np.interp(t_tip, ft, data.force_z_n)
            # tip samples inside a gap of the force stream get no label (the interpolation
            # across it made a 1.5 s gap read as swing: stance 0.71 -> 0.57 of the cycle,
            # P_stance -18 %, silently); the power samples there are left out
            gap = _far_from(t_tip, ft)
            z_tip = data.tip_z_m[tm]
            if gap.any():
                force_gaps.add(s['session_id'])
                t_tip, fz, z_tip = t_tip[~gap], fz[~gap], z_tip[~gap]
            st = stance_mask(fz, z_tip, force_threshold_n=force_threshold_n,
                             height_margin_m=height_margin_m)
            splits['contact'] = splits.get('contact', 0) + 1
            by_contact = True
        else:
            t_tip, st = np.empty(0), np.empty(0, bool)
        duty = s['duty_factor']
        if not duty > 0:
            # not given (a sessions CSV without it, no /gait/phase): Brodoline et al.'s 0.5,
            # said with the measured stance fraction (a bench at 0.6 read +20 % stance and
            # -20 % swing power in silence). The measured fraction is no substitute: the
            # sensed contact outlasts the commanded stance (0.7 at 0.5 on the simulated bench)
            duty = 0.5
            if s['frequency_hz'] > 0 and st.size:
                guessed.append(float(np.mean(st)))
        label_gap = None
        if t_tip.size > 2:
            label_gap = max(LABEL_GAP_INTERVALS * float(np.median(np.diff(t_tip))), 0.05)
            if not np.all(np.diff(t_tip) <= label_gap):
                label_gaps.add(s['session_id'])
        if by_contact and t_tip.size:
            # a pause inside the walk (the leg stands, then walks on) is standing: its samples
            # are in neither phase, and the walk after it is taken in whole cycles from its end
            # (the joints show where the leg stops and walks on; else the tip's ground times,
            # which also add the pauses joints did not see: a servo hunting by 1 deg while
            # paused, 2 s at 0.5 Hz, read P_stance +9.7 %, P_swing -33 % without a warning)
            rows = _add_pauses(_joint_pauses(data, t0, t1, s['frequency_hz'], duty),
                               _tip_pauses(data.tip_t_s, data.tip_z_m, t0, t1,
                                           s['frequency_hz']))
            rows = rows[(rows[:, 3] > a) & (rows[:, 2] < t1)]
            if rows.size:
                keep = np.ones(t_tip.shape, bool)
                for p0, p1 in rows[:, 2:]:
                    keep &= ~((t_tip >= p0) & (t_tip < p1))
                resume = float(np.max(rows[:, 3]))
                if resume > a:
                    f = s['frequency_hz']
                    t1 = resume + math.floor(max(t1 - resume, 0.0) * f + CYCLE_TOLERANCE) / f
                keep &= t_tip < t1
                t_tip, st = t_tip[keep], st[keep]
                paused[s['session_id']] = rows[:, 2:]
                # read_bench_bag's warning of the same pause (over PAUSE_GROUND) says it is
                # analysed as walking: no longer so
                warnings = [w for w in warnings if not (
                    w.startswith(f'session {s["session_id"]}: its leg tip makes no step for ')
                    and w.endswith('the standing there is analysed as walking'))]
                warnings.append(
                    f'session {s["session_id"]}: its leg tip makes no step for '
                    f'{float(np.sum(rows[:, 1] - rows[:, 0])):.1f} s in {len(rows)} pause(s) '
                    'inside its walk (' + ', '.join(f'{p0 - t0:.1f}-{p1 - t0:.1f} s'
                                                   for p0, p1 in rows[:3, :2]) +
                    (' ...' if len(rows) > 3 else '') + ' after its \'walking\' message): '
                    'the standing there is left out of both phases')
        labelled.append((s, a, t1, t_tip, st, duty, label_gap, label_clock))
    _check_schedule_contact(data, agreement, phase_split)
    # the power monitor's clock against the labels' (tip or /gait/phase): a 0.2 s offset
    # swapped the phase powers in silence (3 Hz stance 5.21 -> 15.41 W; outside review A, F1)
    lag, lag_diag = _power_lag_s(data, power, labelled, notes, warnings)
    t_power = data.battery_t_s - lag
    changed = []
    for s, a, t1, t_tip, st, duty, label_gap, label_clock in labelled:
        if lag:
            # the session stamps are on one of the two clocks: the window's last |lag| s may
            # be after the walk on the other (standing power read as stance: -3 % at 3 Hz)
            f = s['frequency_hz']
            # whole cycles from the walk's last resumption after a pause (else its start)
            base = max([a] + [float(p1) for _, p1 in paused.get(s['session_id'], ())])
            t1 = t1 - abs(lag) if f <= 0 or (t1 - a) * f < 2 else \
                base + math.floor((t1 - abs(lag) - base) * f + CYCLE_TOLERANCE) / f
        pm = (t_power >= a) & (t_power < t1)
        for p0, p1 in paused.get(s['session_id'], ()):
            pm &= ~((t_power >= p0) & (t_power < p1))
        if not pm.any():
            continue
        kw = dict(session_id=s['session_id'], load_kg=s['load_kg'],
                  frequency_hz=s['frequency_hz'], duty_factor=duty, max_label_gap_s=label_gap,
                  label_clock=label_clock)
        sample = phase_powers(t_power[pm], power[pm], t_tip, st, **kw)
        if s['session_id'] in label_gaps | force_gaps:
            plain = phase_powers(t_power[pm], power[pm], t_tip, st, gap_fill=False, **kw)
            change = max(abs(sample.p_stance_w - plain.p_stance_w) / abs(plain.p_stance_w),
                         abs(sample.p_swing_w - plain.p_swing_w) / abs(plain.p_swing_w)) \
                if plain.p_stance_w and plain.p_swing_w else 0.0
            if change > GAP_CHANGE:
                changed.append((change, str(s['session_id'])))
        # the tip path walked (0 or absent: not recorded, e.g. a sessions file)
        length, height = (float(s.get(k) or 0.0) for k in ('step_length_m', 'step_height_m'))
        if length > 0 and height > 0:
            sample = dataclasses.replace(sample, step_length_m=length, step_height_m=height)
        samples.append(sample)
    if label_gaps or force_gaps:
        streams = (['/bench/ground_force'] if force_gaps else []) + \
            (['/bench/leg_tip or /gait/phase'] if label_gaps - force_gaps else [])
        notes.append(f'{len(label_gaps | force_gaps)} walking session(s) with gaps in the '
                     f'phase labels ({", ".join(streams)}): the power samples in the gaps are '
                     'left out of the phase split, each phase averaged over the cycle\'s '
                     'phase bins')
    if changed:
        worst = max(changed)
        warnings.append(f'{len(changed)} walking session(s) with gaps in the phase labels '
                        'change a phase power by more than '
                        f'{100 * GAP_CHANGE:.0f} % (up to {100 * worst[0]:.1f} % in session '
                        f'{worst[1]}) between a plain average of the labelled samples and the '
                        'one per cycle phase used: check the tip tracking and the force stream '
                        'for dropouts')
    if guessed:
        notes.append(f'bench duty factor not given: 0.5 assumed (Brodoline et al.\'s bench); '
                     f'the sensed stance fraction is {min(guessed):.2f} to {max(guessed):.2f}. '
                     'If the leg was commanded at another duty factor, give it (duty_factor '
                     'in the sessions file): the phase powers scale with it (0.6 read as 0.5: '
                     'stance +20 %, swing -20 %)')
    if phase_split == 'schedule' and splits.get('contact'):
        raise BagContentError(f'bag {data.path}: /gait/phase does not cover '
                              f'{splits["contact"]} walking session(s) '
                              f'({_coverage_reasons(uncovered)}); use the contact split')
    if phase_split == 'auto' and splits.get('schedule') and splits.get('contact'):
        notes.append(f'stance and swing split by the commanded schedule in '
                     f'{splits["schedule"]} walking session(s), by contact in '
                     f'{splits["contact"]} ({_coverage_reasons(uncovered)})')
    diag = {'bag': data.path, 'force_offset_s': offset, 'current_sign': sign,
            'power_lag_s': lag, 'power_lag': lag_diag,
            'force_sign': f_sign, 'sessions': len(samples), 'notes': notes,
            'warnings': warnings,
            'phase_split': ('schedule' if splits.get('schedule') and not splits.get('contact')
                            else 'contact' if splits.get('contact') and
                            not splits.get('schedule') else
                            'mixed' if splits else 'none')}
    return samples, diag


#: a cycle whose commanded stance agrees with the measured contact in fewer than this
#: fraction of its labels disagrees; a schedule that disagrees in more than
#: SCHEDULE_DISAGREE_CYCLES of its cycles is not the bench leg's (stance and swing swapped)
SCHEDULE_AGREE = 0.5
SCHEDULE_DISAGREE_CYCLES = 0.5
#: the key of the bench leg's own schedule in the agreement record
_BENCH_KEY = ''


def _schedule_contact_cycles(data: BenchData, offset: float, a: float, t1: float,
                             frequency_hz: float, t_lab: np.ndarray, stance: np.ndarray,
                             out: dict[str, list[float]], *,
                             force_threshold_n: float | None = None,
                             height_margin_m: float = 0.01) -> None:
    """Per whole cycle of ``[a, t1)``, the fraction of the labels ``t_lab`` where the
    commanded ``stance`` agrees with the contact the bench measures (the force above its
    threshold and the tip low: :func:`stance_mask`), appended to ``out['']``; the same for
    every leg of a several-leg ``/gait/phase`` (:attr:`BenchData.schedule_legs`, from the
    stance code of :attr:`BenchData.gait_rows`) under its name. Labels where the force or
    the tip is not seen are left out."""
    from hexapod_energy.single_leg import stance_mask

    if t_lab.size < 8 or data.force_t_s.size < 4 or data.tip_t_s.size < 4:
        return
    ft = data.force_t_s + offset
    seen = ~(_far_from(t_lab, ft) | _far_from(t_lab, data.tip_t_s))
    if seen.sum() < 8:
        return
    t = t_lab[seen]
    fz = np.interp(t, ft, data.force_z_n)
    z = np.interp(t, data.tip_t_s, data.tip_z_m)
    if not np.ptp(fz) > 0:
        return
    contact = stance_mask(fz, z, force_threshold_n=force_threshold_n,
                          height_margin_m=height_margin_m)
    cycle = np.floor((t - a) * frequency_hz).astype(int)
    n_cycles = int(math.floor((t1 - a) * frequency_hz + CYCLE_TOLERANCE))
    labels: dict[str, np.ndarray] = {_BENCH_KEY: stance[seen]}
    if data.schedule_legs and data.gait_rows.size:
        rows = data.gait_rows
        k = np.clip(np.searchsorted(rows[:, 0], t), 0, len(rows) - 1)
        same = np.abs(rows[k, 0] - t) < 1e-9
        if same.all():
            code = rows[k, 5].astype(np.int64)
            for i, leg in enumerate(data.schedule_legs[:52]):
                labels[leg] = ((code >> i) & 1).astype(bool)
    for key, lab in labels.items():
        for c in range(n_cycles):
            m = cycle == c
            if m.sum() >= 4:
                out.setdefault(key, []).append(float(np.mean(lab[m] == contact[m])))


def _check_schedule_contact(data: BenchData, agreement: dict[str, list[float]],
                            phase_split: str) -> None:
    """Refuse a schedule split whose commanded stance disagrees with the measured contact
    (:func:`_schedule_contact_cycles`) in most cycles: the schedule is not the bench leg's (a
    ``--bench-leg`` of the other tripod swapped every session's phases, Eq. 1 -23 %, silently:
    outside review, A2); names the leg whose schedule agrees when one does."""
    own = agreement.get(_BENCH_KEY, [])
    if phase_split == 'contact' or len(own) < 3:
        return
    bad = sum(x < SCHEDULE_AGREE for x in own)
    if bad <= SCHEDULE_DISAGREE_CYCLES * len(own):
        return
    leg = data.bench_leg or 'the bench leg'
    others = {k: float(np.mean([x >= SCHEDULE_AGREE for x in v]))
              for k, v in agreement.items() if k != _BENCH_KEY and k != data.bench_leg
              and len(v) == len(own)}
    good = sorted((k for k, v in others.items() if v > 1.0 - SCHEDULE_DISAGREE_CYCLES),
                  key=lambda k: (-others[k], k))
    hint = (f'the schedule of {", ".join(good)} agrees in {100 * others[good[0]]:.0f} % of '
            f'the cycles: is the bench leg {" or ".join(good)} (--bench-leg {good[0]})?'
            if good else
            'no leg of /gait/phase agrees: check in_stance and the force and tip streams')
    raise BagContentError(
        f'bag {data.path}: the commanded stance of {leg} on /gait/phase disagrees with the '
        f'contact the bench measures (force and leg tip) in {bad} of {len(own)} walking '
        f'cycles (mean agreement {100 * float(np.mean(own)):.0f} %): split by it, stance and '
        f'swing would be swapped. {hint} (--phase-split contact splits by the contact '
        'instead)')


def _force_offset_s(data: BenchData, segments: list[tuple[dict[str, Any], float, float]],
                    notes: list[str], warnings: list[str]) -> float:
    """Offset to add to the force stamps [s] (:func:`align_offset_sessions_s` over the walking
    sessions, each weighted by its number of cycles); what needs saying goes to ``notes`` and
    ``warnings``."""
    streams, name = [], []
    for s, t0, t1 in segments:
        f = s['frequency_hz']
        if f <= 0:
            continue
        fm = (data.force_t_s >= t0) & (data.force_t_s < t1)
        tm = (data.tip_t_s >= t0) & (data.tip_t_s < t1)
        if fm.sum() < 4 or tm.sum() < 4:
            continue
        streams.append((data.force_t_s[fm], data.force_z_n[fm], data.tip_t_s[tm],
                        data.tip_z_m[tm], float(f), f * (t1 - t0)))
        name.append(str(s['session_id']))
    try:
        offset, info = align_offset_sessions_s(streams)
    except ValueError:
        return 0.0
    if info['realiased']:
        notes.append(f'force-to-tip offset {offset:+.3f} s from all walking sessions\' '
                     f'correlations together: {len(info["realiased"])} session(s) would alone '
                     'have read another period\'s peak, or clipped this one')
    problems = []
    if info['ambiguous']:
        problems.append('the sessions\' combined correlation has several peaks as high (the '
                        'offset is ambiguous by a common period of the frequencies walked)')
    if info['edge']:
        problems.append(f'the peak is at the edge of the search (+-{info["search_s"]:.2f} s)')
    if info['disagree']:
        problems.append(f'{len(info["disagree"])} of {len(info["per_session"])} session(s) do '
                        'not peak there (' + ', '.join(name[k] for k in info['disagree'][:5]) +
                        ')')
    if problems:
        warnings.append(f'bench force-to-tip offset {offset:+.3f} s is uncertain: ' +
                        '; '.join(problems) + '. Check the force and tip clocks; the contact '
                        'split depends on it')
    return offset


#: a walking session whose label gaps change a phase power by more than this fraction (the
#: per-cycle-phase average against the plain one) is a warning, not only a note
GAP_CHANGE = 0.01
#: a power-to-label lag below this is not applied [s] (without a clock offset the simulated
#: bench, hexapod-sim bench --seed 2, reads +0.010 s: a constant part of its servos' delay;
#: outside review A's synthetic bench 0.001 s)
POWER_LAG_MIN_S = 0.02
#: the lag is applied when its jackknife standard error is below this [s] ...
POWER_LAG_SE_S = 0.01
#: ... no other peak of the explained variance reaches this fraction of the main one ...
POWER_LAG_SECOND = 0.9
#: ... and at least this fraction of the sessions agree on it
POWER_LAG_AGREE = 0.75


def _power_lag_s(data: BenchData, power: np.ndarray,
                 labelled: list[tuple[dict[str, Any], float, float, np.ndarray, np.ndarray,
                                      float, float | None, np.ndarray | None]],
                 notes: list[str], warnings: list[str]) -> tuple[float, dict[str, Any]]:
    """The lag of the power stream behind the phase labels to take out [s] (0 unless clear:
    :func:`power_label_lag_s` over the walking sessions; :data:`POWER_LAG_MIN_S` ..
    :data:`POWER_LAG_AGREE`), and its diagnostics; applied or ambiguous lags are said in
    ``notes`` and ``warnings``. A lag within three standard errors of 0 is none; with one
    walking frequency nothing is estimated (noted). The labels are the schedule's timeline
    where its clock is known (:func:`~hexapod_energy.single_leg.schedule_labels`), as in the
    phase split."""
    rows = []
    for s, a, t1, t_tip, st, _duty, gap, clock in labelled:
        if s['frequency_hz'] <= 0 or len(t_tip) < 4 or st.all() or not st.any():
            continue
        pm = (data.battery_t_s >= a) & (data.battery_t_s < t1)
        rows.append((data.battery_t_s[pm], power[pm], t_tip, st, gap, s['frequency_hz'],
                     clock))
    try:
        r = power_label_lag_s(rows)
    except ValueError:
        return 0.0, {}
    lag, se = r['lag_s'], r['se_s']
    if r['frequencies'] < 2:
        notes.append('the power stream\'s clock not checked against the phase labels\': one '
                     'walking frequency cannot tell a clock offset from the waveform\'s own '
                     'delay')
        return 0.0, r
    if abs(lag) < POWER_LAG_MIN_S or not abs(lag) > 3 * se:
        return 0.0, r   # no offset, or none told from the sessions' scatter
    what = (f'the power stream (/battery_state) lags the phase labels by {lag:+.3f} s '
            f'(+- {se:.3f} s over {r["sessions"]} walking sessions at {r["frequencies"]} '
            'frequencies, besides a phase-locked delay of '
            f'{r["phase_lag"]:+.2f} cycle; the stance/swing split explains '
            f'{100 * r["explained"]:.0f} % of the power variance there, '
            f'{100 * r["explained_at_zero"]:.0f} % at 0 s)')
    if r['alias_s'] <= 2 * MAX_POWER_LAG_S:
        what += (f'; {lag - math.copysign(r["alias_s"], lag):+.3f} s would fit about as well '
                 '(at a duty factor of 0.5 stance and swing swap every half period; the '
                 'common half period of the frequencies walked is '
                 f'{r["alias_s"]:.3g} s): the smaller is taken')
    problems = []
    if not se <= POWER_LAG_SE_S:
        problems.append('its standard error is large')
    if r['second'] >= POWER_LAG_SECOND and (r['frequencies'] < 3 or
                                            not abs(r['second_lag_s']) > abs(lag)):
        # a comparable peak at a smaller offset: ambiguous. One further out loses to the
        # smaller offset as the exact aliases do (review D: on the default plan, 0.5-3 Hz,
        # 0.05 and 0.1 s were found and not applied for their -0.45 / -0.4 s partial
        # aliases, which only the 0.5 Hz sessions tell apart). Not with two frequencies:
        # they fix d and phi with nothing left over, and a broad waveform's split leaves
        # peaks that no third frequency tells apart (simulated bench, 0.75 and 1.5 Hz, 5
        # loads: a 0.3 s offset read -0.130 s, 0.12 s read 0.072 s, each peak beside one
        # of 93-95 % further out)
        problems.append(f'another lag ({r["second_lag_s"]:+.3f} s) explains '
                        f'{100 * r["second"]:.0f} % as much' +
                        (' (two walking frequencies: no third tells the two apart)'
                         if r['frequencies'] < 3 else ''))
    if r['agree'] < POWER_LAG_AGREE * r['sessions']:
        problems.append(f'only {r["agree"]} of {r["sessions"]} sessions peak there (a '
                        'phase-locked waveform, not a clock offset?)')
    if r['edge']:
        problems.append(f'it is at the edge of the search (+-{r["search_s"]:.2f} s)')
    if problems:
        warnings.append(f'{what}: not applied, since ' + '; '.join(problems) + '. Check the '
                        'power monitor\'s clock against the tip tracking or /gait/phase: the '
                        'phase powers depend on it')
        return 0.0, r
    msg = (f'{what}: the power stamps were moved back by it before the phase split (a clock '
           'offset between the power monitor and the labels\' stream; the phase powers change '
           'with it)')
    notes.append(msg)
    warnings.append(msg)
    return float(lag), r


#: a session's frequency (``/bench/session``, or the sessions file) further than this fraction
#: from the step frequency ``/gait/phase`` walked is a mismatch (:func:`_walked_segments`)
FREQUENCY_MISMATCH = 0.03


def _walked_segments(data: BenchData, segments: list[tuple[dict[str, Any], float, float]],
                     warnings: list[str]) -> list[tuple[dict[str, Any], float, float]]:
    """The walking segments with each session's frequency checked against the step frequency
    ``/gait/phase`` recorded over it (the median of ``1 / period``, 0 while standing).

    A session whose recorded schedule walked another frequency (beyond
    :data:`FREQUENCY_MISMATCH`), or walked when it should stand or stood when it should walk,
    is analysed at what the leg walked: the frequency, duty factor and step length and height
    of ``/gait/phase`` replace the session's, and a warning names the session. Why not refuse:
    the power, force and tip streams are those of the walked schedule (the phase split takes
    its stance labels from the same ``/gait/phase``), so the session is a good sample of that
    frequency under its load, only mislabelled; refusing would discard a whole bench for one
    sequencer that never commanded the gait node (outside review D1: every "2 Hz" session of a
    plan walked the gait node's default 1 Hz, and read as 2 Hz: 10.40 / 5.23 W). A 0 Hz
    session whose legs all stay in stance on ``/gait/phase`` stands, whatever its period.
    Segments without ``/gait/phase`` (fewer than 4 messages) are kept as they are."""
    rows = data.gait_rows
    if not rows.size:
        return segments
    out = []
    for s, t0, t1 in segments:
        m = (rows[:, 0] >= t0) & (rows[:, 0] < t1)
        if m.sum() < 4:
            out.append((s, t0, t1))
            continue
        seg = rows[m]
        walked = float(np.median(seg[:, 1]))
        label = float(s['frequency_hz'])
        if walked > 0 and np.all(seg[:, 5] == seg[0, 5]) and (t1 - t0) * walked >= 1.5:
            walked = 0.0   # a period, but every leg kept its stance: standing
        if label > 0 and walked > 0:
            same = abs(walked - label) <= FREQUENCY_MISMATCH * label
        else:
            same = (label > 0) == (walked > 0)
        if same and walked > 0:
            other = _walked_gait_mismatch(s, seg)
            if other:
                fixed = dict(s)
                for key, _label, value in other:
                    fixed[key] = value
                warnings.append(
                    f'session {s["session_id"]}: ' + ', '.join(
                        f'{key} labelled {lab:.4g} but /gait/phase walked {val:.4g}'
                        for key, lab, val in other) +
                    ': analysed at the walked values. Was the gait node commanded '
                    '(bench_sequencer gait_node)?')
                out.append((fixed, t0, t1))
                continue
        if same:
            out.append((s, t0, t1))
            continue
        fixed = dict(s, frequency_hz=walked)
        if walked > 0:
            for key, col in (('duty_factor', 2), ('step_length_m', 3), ('step_height_m', 4)):
                v = seg[:, col][seg[:, col] > 0]
                if v.size:
                    fixed[key] = float(np.median(v))
        warnings.append(
            f'session {s["session_id"]}: labelled {label:.4g} Hz but /gait/phase walked '
            f'{walked:.4g} Hz' + (f' (period {1 / walked:.4g} s)' if walked > 0 else
                                  ' (the legs stood)') +
            ': analysed at the walked frequency (with its duty factor and step). Was the gait '
            'node commanded (bench_sequencer gait_node)?')
        out.append((fixed, t0, t1))
    return out


def _walked_gait_mismatch(s: dict[str, Any], seg: np.ndarray
                          ) -> list[tuple[str, float, float]]:
    """``(key, label, walked)`` of the session's duty factor and step length that differ
    from what ``/gait/phase`` walked over it by more than :data:`FREQUENCY_MISMATCH` (a
    sessions file without them, or a schedule without them, is not compared)."""
    out = []
    for key, col in (('duty_factor', 2), ('step_length_m', 3)):
        label = s.get(key)
        v = seg[:, col][seg[:, col] > 0]
        if not isinstance(label, (int, float)) or not math.isfinite(label) or label <= 0 \
                or not v.size:
            continue
        walked = float(np.median(v))
        if abs(walked - label) > FREQUENCY_MISMATCH * label:
            out.append((key, float(label), walked))
    return out


def force_sign_factor(data: BenchData, segments: list[tuple[dict[str, Any], float, float]],
                      mode: str = 'auto') -> tuple[float, str]:
    """Factor (+1 or -1) that makes the bench's normal force positive in compression, and a
    note ('' when nothing needs saying).

    ``auto``: a leg standing still (a 0 Hz session) carries its load on the treadmill all the
    time, a walking leg only in stance, so under the same load the static session's mean force
    lies above the walking sessions' when compression is positive, below when it is negative,
    whatever the sensor's zero offset. The sign is the median over loads that have both; with
    no static session the force is taken as recorded (noted).
    """
    if mode == 'positive':
        return 1.0, ''
    if mode == 'negative':
        return -1.0, 'force sign negative as given: force.z negated'
    if mode != 'auto':
        raise ValueError(f'force sign must be auto, positive or negative, got {mode!r}')
    static: dict[float, list[float]] = {}
    walking: dict[float, list[float]] = {}
    for s, t0, t1 in segments:
        m = (data.force_t_s >= t0) & (data.force_t_s < t1)
        if m.sum() < 4:
            continue
        load = round(float(s['load_kg']), 4)
        (static if s['frequency_hz'] <= 0 else walking).setdefault(load, []).append(
            float(np.mean(data.force_z_n[m])))
    diffs = [np.mean(static[k]) - np.mean(walking[k]) for k in static if k in walking]
    if not diffs:
        # no static session to compare with: the tip decides. In stance the tip is low and
        # the leg presses on the treadmill, so the force in compression falls as the tip rises
        r = _force_tip_correlation(data, segments)
        if math.isfinite(r) and r > TIP_SIGN_R:
            return -1.0, (f'bench force negative in compression (it rises with the leg tip\'s '
                          f'height while walking, r = {r:+.2f}; no 0 Hz session to compare): '
                          'force.z negated (--force-sign positive keeps it as recorded)')
        if math.isfinite(r) and r < -TIP_SIGN_R:
            return 1.0, ''
        return 1.0, ('force sign not checked (no 0 Hz session with a walking session of the '
                     'same load, and the force does not follow the tip height): force.z taken '
                     'as positive in compression')
    if float(np.median(diffs)) < 0:
        return -1.0, ('bench force negative in compression (static sessions below walking '
                      'ones under the same load): force.z negated (--force-sign positive keeps '
                      'it as recorded)')
    return 1.0, ''


#: |correlation| of force and tip height over walking sessions that decides the force sign
#: when no static session can
TIP_SIGN_R = 0.3
#: a leg tip whose height spans less than this over walking sessions is not the height [m]
FLAT_TIP_M = 0.002


def _force_tip_correlation(data: BenchData,
                           segments: list[tuple[dict[str, Any], float, float]]) -> float:
    """Correlation of the normal force with the tip height over the walking sessions (each
    session's means removed), NaN without enough samples."""
    fs, zs = [], []
    for s, t0, t1 in segments:
        if s['frequency_hz'] <= 0:
            continue
        m = (data.tip_t_s >= t0) & (data.tip_t_s < t1)
        if m.sum() < 10 or data.force_t_s.size < 4:
            continue
        z = data.tip_z_m[m]
        f = np.interp(data.tip_t_s[m], data.force_t_s, data.force_z_n)
        fs.append(f - np.mean(f))
        zs.append(z - np.mean(z))
    if not fs:
        return math.nan
    f, z = np.concatenate(fs), np.concatenate(zs)
    if not (np.std(f) > 0 and np.std(z) > 0):
        return math.nan
    return float(np.corrcoef(f, z)[0, 1])


@dataclass
class RobotRun:
    """Whole-cycle measurement of one robot bag.

    ``power_out_w`` is from joint efforts (nan when the bag has none); ``gait`` holds the last
    ``/gait/phase`` sample's schedule.
    """

    path: str
    windows: int
    window_s: float
    power_in_w: float
    power_out_w: float
    speed_mps: float
    gait: Any
    payload_kg: float | None
    current_sign: float
    extra: dict[str, Any] = field(default_factory=dict)


def read_robot_bag(path: str | Path, *, mass_kg: float, current_sign: str = 'auto',
                   cycles: int = 1, speed_mps: float | None = None,
                   cycle_source: str = 'auto', segment: int | None = None) -> RobotRun:
    """Whole-gait-cycle averages of one robot bag, computed by the same accumulator as the
    ``energy_monitor`` node (so live and offline numbers agree).

    Bags without ``/gait/phase`` (robots running their own gait code): the cycles come from the
    joint positions (:mod:`hexapod_energy.cycles`; ``cycle_source`` ``auto`` does this when the
    bag has no ``/gait/phase``, ``joints`` always); the speed from ``/mocap/body``, else
    ``/odom`` (nav_msgs/Odometry, position differenced in the odometry frame), else
    ``speed_mps``, else NaN; P_out from the joint efforts, else NaN. ``gait`` is then None and
    ``extra`` holds ``cycle_source``, ``speed_source``, ``period_s`` (mean window length /
    ``cycles``), ``leg_names`` (from the joint names ``<leg>_<joint>``) and a note for each
    fallback. Bags with ``/gait/phase`` messages are read exactly as before; a ``/gait/phase``
    connection without messages counts as none (``auto``), with a note.

    Schedules: a bag whose ``/gait/phase`` changes schedule (a speed sweep, a gait switch, a
    stop) holds several runs. Windows are grouped by the walking schedule in force over them
    (windows across a change, and standing, are left out, noted); ``segment`` picks one
    (0-based, in time order; default the one with the most windows) and ``extra['segment']``
    says which (``index``, ``of``, ``t_start_s``, ``t_end_s``); ``gait`` is that schedule's.
    :func:`read_robot_segments` reads every one.
    """
    out = _read_robot(path, mass_kg=mass_kg, current_sign=current_sign, cycles=cycles,
                      speed_mps=speed_mps, cycle_source=cycle_source, segment=segment)
    assert isinstance(out, RobotRun)
    return out


def _read_robot(path: str | Path, *, mass_kg: float, current_sign: str = 'auto',
                cycles: int = 1, speed_mps: float | None = None,
                cycle_source: str = 'auto', segment: int | None = None,
                all_segments: bool = False) -> RobotRun | list[RobotRun]:
    """Body of :func:`read_robot_bag` and :func:`read_robot_segments`."""
    from hexapod_common.bags import SampleColumns, iter_messages, open_reader
    from hexapod_common.clocks import ClockCheck
    from hexapod_common.conversions import (
        battery_from_msg,
        gait_phase_from_msg,
        joint_state_from_msg,
        odometry_from_msg,
        pose_from_msg,
    )

    from hexapod_energy.descriptors import (
        BATTERY_GAP_NOTE,
        JOINT_GAP_NOTE,
        LEG_MISMATCH_NOTE,
        PARTIAL_POSE_NOTE,
        POSE_FALLBACK_NOTE,
        SCHEDULE_SPEED_NOTE,
        STILL_JOINTS_NOTE,
        ZERO_EFFORT_NOTE,
        POSITION_POWER_NOTE,
        SLOW_BATTERY_NOTE,
        DescriptorAccumulator,
        resolve_current_sign,
        velocityless_note,
    )

    if cycle_source not in ('auto', 'gait_phase', 'joints'):
        raise ValueError(f'cycle_source must be auto, gait_phase or joints, got {cycle_source!r}')
    with open_reader(path) as reader:
        present = {c.topic for c in reader.connections}
        bench_like = any(c.topic in ('/bench/session', '/bench/ground_force') and c.msgcount
                         for c in reader.connections)
    if bench_like:
        # a single-leg bench bag read as a robot gave 'runs' of a one-legged tripod
        raise BagContentError(
            f'bag {path} is a single-leg bench bag (/bench/session, /bench/ground_force), not '
            'a robot run: give it with --bench')
    auto_cycles = cycle_source == 'auto'
    if auto_cycles:
        cycle_source = 'gait_phase' if '/gait/phase' in present else 'joints'
    required = ROBOT_TOPICS if cycle_source == 'gait_phase' else ('/battery_state',
                                                                    '/joint_states')
    windows = []
    gait = None
    notes: list[str] = []
    if '/tf' in present and '/mocap/body' not in present and \
            not os.environ.get(MOCAP_TF_ENV, '').strip():
        # as `slip` says it (an outside review: the speed came out null with no pointer)
        notes.append('no /mocap/body, but /tf is recorded: motion capture broadcast as tf is '
                     'read with hexapod-analyze --mocap-tf PARENT:CHILD energy ... (e.g. '
                     'world:base_link); without it the speed comes from /odom, the gait '
                     'schedule or --robot-speed')
    converters = {'/battery_state': battery_from_msg, '/gait/phase': gait_phase_from_msg,
                  '/joint_states': joint_state_from_msg, '/mocap/body': pose_from_msg,
                  '/odom': odometry_from_msg}
    # every converted sample, per topic, as compact columns (a 60 min 18-joint bag held as
    # sample objects took 2 GB); ``order`` numbers them in reading order across topics
    stores: dict[str, SampleColumns] = {topic: SampleColumns() for topic in converters}
    order: dict[str, array.array] = {topic: array.array('q') for topic in converters}
    n_samples = 0
    seen: dict[tuple[str, bytes], None] = {}
    zero_stamps: dict[str, int] = {}
    dropped: dict[str, list[str]] = {}
    malformed: dict[str, list[str]] = {}
    duplicates = 0
    exact: dict[str, int] = {}   # same topic, log time and bytes: dropped by iter_messages
    n_battery = 0
    clocks = ClockCheck()
    with open_reader(path) as reader:
        _check_topics(reader, required, str(path))
        custom = _custom_data(reader)
        notes.extend(getattr(reader, 'notes', ()))  # e.g. mcap files without metadata.yaml
        topics = ROBOT_TOPICS + ('/joint_states', '/mocap/body', '/odom')
        for m in iter_messages(reader, topics, duplicates=exact):
            msg = reader.deserialize(m.data, m.msgtype)
            n_battery += m.topic == '/battery_state'
            try:
                sample = converters[m.topic](msg)
            except (ValueError, IndexError) as err:  # a bad message is dropped, as live
                dropped.setdefault(m.topic, []).append(str(err))
                continue
            if getattr(sample, 'malformed', ''):   # efforts of another length: left out
                malformed.setdefault(m.topic, []).append(sample.malformed)
            if sample.t_s != 0.0:
                clocks.observe(m.topic, sample.t_s, 1e-9 * m.stamp_ns)
                # the same stamped message recorded twice (two recorders, a relay, a bridge)
                key = (m.topic, m.data)
                if key in seen:
                    duplicates += 1
                    continue
                seen[key] = None
                if len(seen) > 4096:  # duplicates arrive close together: keep recent ones
                    del seen[next(iter(seen))]
            else:
                # drivers that leave header.stamp at 0: the bag's receive time stands in
                # (a stamp of 0 received at bag time 0 is a clock that starts at 0: no note)
                if m.stamp_ns != 0:
                    zero_stamps[m.topic] = zero_stamps.get(m.topic, 0) + 1
                sample = dataclasses.replace(sample, t_s=1e-9 * m.stamp_ns)
            stores[m.topic].append(sample)
            order[m.topic].append(n_samples)
            n_samples += 1
    del seen
    _on_one_clock(stores, clocks, notes)
    bad_battery = dropped.get('/battery_state', [])
    if bad_battery and len(bad_battery) == n_battery:
        raise BagContentError(
            f'bag {path}: no usable /battery_state message ({n_battery} of {n_battery} '
            f'dropped, e.g. {bad_battery[0]}): input power needs both voltage and current')
    for topic, errs in sorted(dropped.items()):
        notes.append(f'{len(errs)} {topic} message(s) dropped: {errs[0]}')
    for topic, errs in sorted(malformed.items()):
        notes.append(f'{len(errs)} {topic} message(s) with {errs[0]} (positions kept)')
    for topic, n in sorted(zero_stamps.items()):
        notes.append(f'{n} {topic} message(s) with a zero header stamp: bag receive time used')
    duplicates += sum(exact.values())
    if duplicates:
        notes.append(f'{duplicates} duplicated message(s) ignored')
    n_gait = len(stores['/gait/phase'])
    if auto_cycles and cycle_source == 'gait_phase' and n_gait == 0:
        # an advertised but silent /gait/phase (``ros2 bag record -a``): the joints decide
        n_bad = len(dropped.get('/gait/phase', []))
        if not len(stores['/joint_states']):
            raise BagContentError(
                f'bag {path}: /gait/phase has no ' + ('usable ' if n_bad else '') +
                'messages and /joint_states none either: no gait cycles to average over')
        cycle_source = 'joints'
        notes.append('/gait/phase recorded but ' +
                     (f'none of its {n_bad} message(s) usable' if n_bad else
                      'without messages') +
                     ': cycle boundaries from the joint positions')
    if not len(stores['/battery_state']):
        raise BagContentError(
            f'bag {path}: /battery_state has no ' + ('usable ' if n_battery else '') +
            'messages' + (f' (all {n_battery} dropped)' if n_battery else '') +
            ': input power needs the battery voltage and current')
    _prepare_battery_store(path, stores, order, n_samples, notes)
    glitch_t = _battery_glitch_stamps(stores['/battery_state'], notes)
    if current_sign == 'auto':
        # offline the whole run decides (the median of V * I), never its first samples: a
        # sensor's idle offset before the servos draw current must not flip a run's P_in
        bat = stores['/battery_state']
        sign = resolve_current_sign(np.asarray(bat.column('voltage_v'), dtype=float),
                                    np.asarray(bat.column('current_a'), dtype=float), 'auto')
        current_sign = 'ros' if sign < 0 else 'positive_discharge'
        if sign > 0:  # the contract's convention needs no word; the other does
            notes.append('battery current sign auto-detected from the median of V * I over '
                         'the run: positive while discharging (not the ROS convention)')
    # raw effort P_out per window: the command decides effort against model per run
    acc = DescriptorAccumulator(mass_kg=mass_kg, cycles=cycles, current_sign=current_sign,
                                power_out_source='effort', cycle_source=cycle_source,
                                speed_mps=speed_mps or 0.0)
    # offline the whole bag says whether it names leg joints: nothing is held (a gripper's
    # message before the legs' is left out, a bag of other names is read whole)
    name_sets = list(stores['/joint_states'].distinct('names'))
    acc.leg_joints_ = LegJointFilter(legs_present=LegJointFilter.names_have_legs(name_sets))
    # every joint name the run records (the command checks the legs' joints against the
    # Eq. 6 model's 3-DOF leg)
    all_joint_names = sorted({str(n) for names in name_sets for n in names})
    changes: list[tuple[Any, ...]] = []   # schedule changes on /gait/phase, with history
    # header-stamp order (recorders store receive order; stamps may be a few ms out of order),
    # each sample rebuilt from the columns as it is fed
    for topic, sample in _stamp_ordered(stores, order):
        if topic == '/battery_state':
            if glitch_t and sample.t_s in glitch_t:
                continue
            windows.extend(acc.add_battery(sample))
        elif topic == '/gait/phase':
            gait = sample
            key = _schedule_key(sample)
            if not changes or not _same_schedule(changes[-1][1], key):
                changes.append((sample.t_s, key, sample, [(sample.t_s, sample.t_s, sample)]))
            else:
                # the schedule's latest sample stands for it: the first one within the
                # tolerance may still be settling (beta 0.7499711 for 0.75 after a transition);
                # a window takes the one in force at its end (_window_schedule): the latest
                # may be the next transition's start (a stand: step 79.91 mm for 80 mm)
                _note_schedule_sample(changes[-1][3], sample)
                changes[-1] = (changes[-1][0], changes[-1][1], sample, changes[-1][3])
            windows.extend(acc.add_gait_phase(sample))
        elif topic == '/joint_states':
            windows.extend(acc.add_joint_state(sample) or ())
        elif topic == '/odom':
            acc.add_odometry(sample)
        else:
            acc.add_pose(sample)
    # efforts count only when they gave a joint power (with velocities, or without them
    # from position differences); efforts alone leave P_out unknown, not 0 W
    has_effort = acc.joint_power_samples_ > acc.zero_effort_samples_
    if acc.joint_power_samples_ and not has_effort:
        # a driver without an effort interface filling effort with 0.0: P_out 0 W and
        # efficiency 0 were reported as measured (outside review, A3); as without efforts
        notes.append(f'{ZERO_EFFORT_NOTE} (all {acc.joint_power_samples_} samples): P_out '
                     'not from the efforts')
    if acc.repeated_poses_:
        notes.append(f'{acc.repeated_poses_} /mocap/body sample(s) repeat the previous pose '
                     'exactly (the bridge repeating its last pose after losing the body): '
                     'left out of the speed')
    if acc.nonfinite_poses_:
        notes.append(f'{acc.nonfinite_poses_} /mocap/body sample(s) with a non-finite position '
                     '(NaN: the bridge lost the body?) left out of the speed')
    if any(POSITION_POWER_NOTE in d.warnings for d in windows):
        notes.append(POSITION_POWER_NOTE)
    if acc.velocityless_skipped_:
        notes.append(velocityless_note(acc.velocityless_skipped_))
    if acc.leg_joints_.note():
        notes.append(acc.leg_joints_.note())
    if acc.nonfinite_joint_power_:
        bad = acc.nonfinite_joint_power_
        never = sorted(n for n in bad if acc.joint_power_count_.get(n, 0) == 0)
        some = sorted(n for n in bad if n not in never)
        if never and not acc.joint_power_count_:
            notes.append(f'no finite effort * velocity on any joint ({", ".join(never)}; '
                         'NaN: no effort interface?): no P_out from the efforts')
        elif never:
            notes.append(f'no finite effort * velocity on joint(s) {", ".join(never)} (NaN: '
                         'no effort interface?): P_out from the other joints only')
        if some:
            notes.append('non-finite effort or velocity in some samples of joint(s) ' +
                         ', '.join(f'{n} ({bad[n]} of {bad[n] + acc.joint_power_count_[n]})'
                                   for n in some) + ': those samples left out of P_out')
    n_gap = sum(BATTERY_GAP_NOTE in d.warnings for d in windows)
    if n_gap:
        windows = [d for d in windows if BATTERY_GAP_NOTE not in d.warnings]
        notes.append(f'{n_gap} window(s) across a gap in /battery_state (P_in would be '
                     'interpolated over missing data) left out')
    n_gap = sum(JOINT_GAP_NOTE in d.warnings for d in windows)
    if n_gap:
        windows = [d for d in windows if JOINT_GAP_NOTE not in d.warnings]
        notes.append(f'{n_gap} window(s) across a gap in /joint_states (P_out from the efforts '
                     'would miss part of them) left out')
    n_still = sum(any(w.startswith(STILL_JOINTS_NOTE) for w in d.warnings) for d in windows)
    if n_still:
        windows = [d for d in windows
                   if not any(w.startswith(STILL_JOINTS_NOTE) for w in d.warnings)]
        notes.append(f'{n_still} window(s) left out: {STILL_JOINTS_NOTE} (their speed and '
                     'model P_out would be a walking robot\'s)')
    for start in (POSE_FALLBACK_NOTE, PARTIAL_POSE_NOTE):
        # a window whose motion capture was lost around a bound took the gait schedule's
        # speed in silence (an occlusion every 5 s, 0.16 s between poses: run speed -4 %,
        # an outside review); now the window says so, and the run too
        said = [w for d in windows for w in d.warnings if w.startswith(start)]
        if said:
            n_said = sum(any(w.startswith(start) for w in d.warnings) for d in windows)
            notes.append(f'{start} in {n_said} of {len(windows)} window(s), e.g. ' +
                         said[0][len(start) + 2:])
    n_neg = sum(d.power_in_w < 0 for d in windows)
    if n_neg:
        notes.append(f'negative mean input power in {n_neg} of {len(windows)} window(s) with '
                     f'the current sign {current_sign}: check the battery current sign '
                     '(--current-sign)')
    # joint velocities against the positions' derivative at the bag's end (the windows took
    # them as the samples came, as live): deg/s velocities read P_out 57x (outside review B1);
    # a unit recognised is converted (said here once), a factor of no unit refused
    units = acc.joint_units_()
    if units.note and acc.joint_power_samples_:
        notes.append(units.note)
    fast = sorted({w for d in windows for w in d.warnings if w.startswith(SCHEDULE_SPEED_NOTE)})
    if fast:
        notes.append(fast[0])
    legs_differ = sorted({w for d in windows for w in d.warnings
                          if w.startswith(LEG_MISMATCH_NOTE)})
    if legs_differ:
        # said on every live window, dropped offline: an 8-leg robot under a gait node left
        # at leg_count 6 got a 6-leg Eq. 1 prediction in silence (outside review, A4)
        n_legs = sum(any(w.startswith(LEG_MISMATCH_NOTE) for w in d.warnings) for d in windows)
        notes.append(f'{legs_differ[0]} ({n_legs} of {len(windows)} window(s)); the Eq. 1 '
                     'prediction and P_out model are for the legs /gait/phase names' +
                     (f' [{len(legs_differ) - 1} more variant(s)]' if len(legs_differ) > 1
                      else ''))
    n_slow = sum(SLOW_BATTERY_NOTE in d.warnings for d in windows)
    if n_slow:
        notes.append(f'{SLOW_BATTERY_NOTE} ({n_slow} of {len(windows)} window(s))')
    if cycle_source == 'joints':
        runs = _joint_cycle_runs(path, acc, windows, stores['/joint_states'], notes, custom,
                                 has_effort, speed_mps, gait)
        if all_segments:
            return runs
        if segment is None:
            segment = max(range(len(runs)), key=lambda k: runs[k].windows)
        if not 0 <= segment < len(runs):
            raise ValueError(f'segment {segment}: this bag has {len(runs)} step period(s)')
        return runs[segment]
    all_windows = list(windows)
    if not windows and n_still:
        raise BagContentError(
            f'bag {path}: every window ({n_still}) left out: {STILL_JOINTS_NOTE}; /gait/phase '
            'walked a schedule the legs did not follow, so its speed and model P_out would '
            'be false')
    if not windows or gait is None:
        spans = {}
        for topic, store in stores.items():
            t_col = np.asarray(store.column('t_s'), dtype=float)
            if t_col.size:
                spans[topic] = (float(np.min(t_col)), float(np.max(t_col)))
        hint = ''
        bat, gph = spans.get('/battery_state'), spans.get('/gait/phase')
        if bat and gph and (bat[1] < gph[0] or gph[1] < bat[0]):
            hint = (f'; the stamps do not overlap: /battery_state {bat[0]:.3f}..{bat[1]:.3f} s, '
                    f'/gait/phase {gph[0]:.3f}..{gph[1]:.3f} s (stamped on different clocks?)')
        raise BagContentError(
            f'bag {path}: no whole gait cycle with battery samples around it '
            f'(need /gait/phase wrapping at least twice and /battery_state across it){hint}'
        )
    segments = _schedule_segments(windows, changes)
    # a standing robot is a run of its own (its input power, speed 0) when it stood for at
    # least MIN_STAND_WINDOWS windows; a pause between two walks is not
    short = [sg for sg in segments if sg[0].period_s <= 0 and sg[2] < MIN_STAND_WINDOWS]
    segments = [sg for sg in segments if sg not in short]
    if not segments:
        raise BagContentError(f'bag {path}: no whole gait cycle under one walking schedule '
                              '(the schedule on /gait/phase changes within every cycle) and no '
                              f'{MIN_STAND_WINDOWS} s of standing')
    n_mixed = sum(1 for d in all_windows if _window_schedule(d, changes) is None) + \
        sum(sg[2] for sg in short)
    if n_mixed:
        notes.append(f'{n_mixed} window(s) spanning a schedule change (or a short stop) left '
                     'out')
    breaks = acc.schedule_breaks_
    if breaks:
        shown = '; '.join(f'{why} at {t:.2f} s' for t, why in breaks[:3])
        more = f' and {len(breaks) - 3} more' if len(breaks) > 3 else ''
        notes.append(f'{len(breaks)} schedule break(s) on /gait/phase ({shown}{more}): no '
                     'window spans one; the cycles across them were left out (windows '
                     'spanning a schedule change)')
    payload = _find_number(custom, ('payload_kg', 'payload'))
    odd = acc.odometry_disagreements_
    if odd:
        sched, odom = (float(np.median([x[i] for x in odd])) for i in (0, 1))
        notes.append(f'/odom gives {odom:.3g} m/s where the gait schedule gives {sched:.3g} '
                     f'({100 * (odom / sched - 1):+.0f} %, median of {len(odd)} window(s)): '
                     'the schedule\'s speed is used (the paper\'s v = step length / (beta T); '
                     'motion capture, /mocap/body, would decide); with the odometry\'s, CoT, '
                     'CoT/M and specific resistance scale by the inverse ratio')

    def run_of(k: int) -> RobotRun:
        gait_k, t_seg0, _, wins = segments[k]
        seg_notes = list(notes)
        if len(segments) > 1:
            seg_notes.append(f'{len(segments)} walking schedules in this bag: this run is '
                             f'schedule {k + 1} ({_schedule_label(gait_k)}, {len(wins)} '
                             f'window(s) from {t_seg0:.2f} s); each is its own run')
        w = np.array([d.window_s for d in wins])
        avg = lambda xs: float(np.sum(w * np.array(xs)) / np.sum(w))  # noqa: E731
        if any(d.speed_source == 'odometry_twist' for d in wins):
            seg_notes.append(ODOM_TWIST_NOTE)
        n_none = sum(d.speed_source == 'none' for d in wins)
        if n_none:
            too_fast = any(w.startswith(SCHEDULE_SPEED_NOTE) for d in wins
                           for w in d.warnings)
            seg_notes.append(
                f'speed unknown in {n_none} of {len(wins)} window(s) (' +
                ('the gait schedule\'s speed refused as not metres per second'
                 if too_fast else 'a stand or a clock-driven gait schedule, /gait/phase step '
                 'length 0') + ', and no /mocap/body, '
                '/odom or given speed there): '
                + ('speed, cost of transport and specific resistance null'
                   if n_none == len(wins) else 'speed averaged over the others; '
                   'cost of transport and specific resistance over those windows'))
        return RobotRun(
            path=str(path), windows=len(wins), window_s=float(w.sum()),
            power_in_w=avg([d.power_in_w for d in wins]),
            power_out_w=avg([d.power_out_w for d in wins]) if has_effort else math.nan,
            speed_mps=_known_mean(w, [d.speed_mps for d in wins]), gait=gait_k,
            payload_kg=payload, current_sign=float(acc.sign_ or 0.0),
            extra={'custom_data': custom, 'notes': seg_notes, 'cycle_source': 'gait_phase',
                   'joint_name_set': all_joint_names,
                   'speed_source': '+'.join(sorted({d.speed_source for d in wins})),
                   'windows': list(wins), 'speed_span': speed_span(wins, has_effort),
                   'segment': {'index': k, 'of': len(segments), 't_start_s': t_seg0,
                               't_end_s': float(wins[-1].t_end_s)}},
        )

    if all_segments:
        return [run_of(k) for k in range(len(segments))]
    if segment is None:
        segment = max(range(len(segments)), key=lambda k: segments[k][2])
    if not 0 <= segment < len(segments):
        raise ValueError(f'segment {segment}: this bag has {len(segments)} walking schedule(s)')
    return run_of(segment)


#: the key a bag's metadata (``custom_data``, possibly inside a JSON value such as the
#: simulators' ``hexapod_sim.config``) declares the robot's mass under: legs included,
#: payload excluded, as ``--robot-mass``
ROBOT_MASS_KEY = 'robot_mass_kg'


def declared_robot_mass(paths: Sequence[str | Path]) -> tuple[float | None, str]:
    """The robot mass [kg] (payload excluded) the robot bags' metadata declare, and what to
    say about it: ``(kg, note)`` when every bag that declares one declares the same (to
    0.1 g), ``(None, '')`` when none does (or a bag cannot be opened: its reading says why
    later). Bags that declare different masses raise :class:`BagContentError` naming them:
    one run's CoT and specific resistance would be divided by the other robot's mass.
    (``hexapod-sim robot --legs 4`` records 1.851 kg, which the analysis replaced by
    AntBot's 2.183 kg with a warning: CoT/M 15 % low.)"""
    from hexapod_common.bags import open_reader
    from hexapod_common.errors import HexapodError

    found: dict[str, float] = {}
    silent: list[str] = []
    for path in paths:
        try:
            with open_reader(path) as reader:
                kg = _find_number(_custom_data(reader), (ROBOT_MASS_KEY,))
        except (HexapodError, OSError, ValueError):
            continue
        if kg is not None and math.isfinite(kg) and kg > 0:
            found[str(path)] = float(kg)
        else:
            silent.append(str(path))
    if not found:
        return None, ''
    masses = sorted(set(round(v, 4) for v in found.values()))
    if len(masses) > 1:
        each = ', '.join(f'{Path(p).name} {v:.4g} kg' for p, v in found.items())
        raise BagContentError(
            f'the robot bags declare different robot masses ({each}): analyse each robot '
            'apart, or give --robot-mass to use one mass for all')
    kg = float(np.mean(list(found.values())))
    note = f'robot mass {kg:.4g} kg (payload excluded) from the bags\' metadata ' \
           f'({ROBOT_MASS_KEY}; --robot-mass overrides it)'
    if silent:
        names = ', '.join(Path(p).name for p in silent[:3]) + (' ...' if len(silent) > 3 else '')
        note += f'; {len(silent)} bag(s) declare none ({names}) and are taken to be that robot'
    return kg, note


@dataclass(frozen=True)
class RobotMass:
    """The robot mass an analysis divides by (payload excluded), and where it came from."""

    kg: float
    source: str      # '--robot-mass', "bags' metadata" or 'assumed (AntBot...)'
    note: str = ''   # what the bags declared (:func:`declared_robot_mass`), else ''

    @property
    def assumed(self) -> bool:
        """Neither given nor declared: AntBot's mass (or its body with the leg file's legs)
        stands in."""
        return self.source in (ROBOT_MASS_ASSUMED, ROBOT_MASS_ASSUMED_LEG)


#: :attr:`RobotMass.source` of a mass nobody gave (AntBot's)
ROBOT_MASS_ASSUMED = 'assumed (AntBot)'
#: ... with a leg file: AntBot's body and that many of the file's legs
ROBOT_MASS_ASSUMED_LEG = "assumed (AntBot's body with the --leg file's legs)"


def resolve_robot_mass(given_kg: float | None, robot_bags: Sequence[str | Path], *,
                       leg_mass_kg: float | None = None, leg_count: int = 6) -> RobotMass:
    """The robot mass of ``energy`` and ``residuals``: ``given_kg`` (``--robot-mass``), else
    the one the robot bags declare (:func:`declared_robot_mass`; different ones raise), else
    AntBot's :data:`~hexapod_gait.kinematics.ANTBOT_MASS_KG`; with a leg file's leg mass
    (``leg_mass_kg``, ``--leg``), AntBot's body with ``leg_count`` of those legs
    (:func:`~hexapod_gait.kinematics.default_robot_mass_kg`, the simulators' rule: 2.237 kg
    for six 0.175 kg legs, where 2.183 kg was assumed). Each caller words its own warning for
    an assumed mass (what scales with it differs); the value is not checked here (the
    callers refuse a non-positive one with their own error types)."""
    if given_kg is not None:
        return RobotMass(float(given_kg), '--robot-mass')
    if robot_bags:
        kg, note = declared_robot_mass(robot_bags)
        if kg is not None:
            return RobotMass(kg, 'bags\' metadata', note)
    from hexapod_gait.kinematics import ANTBOT_MASS_KG, default_robot_mass_kg

    if leg_mass_kg is None:
        return RobotMass(ANTBOT_MASS_KG, ROBOT_MASS_ASSUMED)
    return RobotMass(default_robot_mass_kg(leg_count, leg_mass_kg), ROBOT_MASS_ASSUMED_LEG)


def read_robot_segments(path: str | Path, **kw: Any) -> list[RobotRun]:
    """Every walking schedule of a robot bag as its own :class:`RobotRun`, in time order, from
    one reading (one run for a bag under a single schedule, or read on joint-derived cycles);
    ``kw`` as :func:`read_robot_bag`."""
    out = _read_robot(path, all_segments=True, **kw)
    assert isinstance(out, list)
    return out


#: note of runs whose speed is the /odom twist's
ODOM_TWIST_NOTE = ('speed from the /odom twist (its pose does not move: a velocity-only '
                   'estimator), the mean horizontal speed over each window')


def _on_one_clock(stores: dict[str, SampleColumns], clocks: Any, notes: list[str]) -> None:
    """Topics stamped on another clock moved onto the others' (:mod:`hexapod_common.clocks`),
    in place."""
    shifts, more = clocks.shifts()
    if not shifts:
        return
    notes.extend(more)
    for topic, dt in shifts.items():
        if topic in stores:
            stores[topic].shift('t_s', dt)


def _prepare_battery_store(path: str | Path, stores: dict[str, SampleColumns],
                           order: dict[str, array.array], n_samples: int,
                           notes: list[str]) -> None:
    """The ``/battery_state`` columns through :func:`hexapod_common.battery.
    prepare_battery_samples` (milli-units scaled, several batteries summed or the one of
    ``--battery-source`` kept), in place; one battery in V and A stays as read. The combined
    samples come after every other in reading order. A stream that measures no power raises
    :class:`BagContentError`."""
    from hexapod_common.bags import prepare_battery_columns

    battery = stores['/battery_state']
    try:
        combined, more = prepare_battery_columns(battery)
    except ValueError as err:
        raise BagContentError(f'bag {path}: {err}') from None
    notes.extend(more)
    if combined is battery or (len(combined) == len(battery) and
                               all(a == b for a, b in zip(combined, battery))):
        return
    stores['/battery_state'] = combined
    order['/battery_state'] = array.array('q', range(n_samples, n_samples + len(combined)))


def _battery_glitch_stamps(battery: SampleColumns, notes: list[str]) -> set[float]:
    """Stamps of isolated battery glitches (:func:`hexapod_energy.descriptors.
    battery_glitches`), noted; they are left out offline (the live monitor, which cannot look
    ahead, keeps them)."""
    from hexapod_energy.descriptors import battery_glitches

    t = np.asarray(battery.column('t_s'), dtype=float)
    p = np.asarray(battery.column('voltage_v'), dtype=float) * \
        np.asarray(battery.column('current_a'), dtype=float)
    o = np.argsort(t, kind='stable')
    mask = np.zeros(t.size, dtype=bool)
    mask[o] = battery_glitches(p[o])
    if not mask.any():
        return set()
    k = int(np.flatnonzero(mask)[np.argmax(np.abs(p[mask]))])
    notes.append(f'{int(mask.sum())} isolated /battery_state sample(s) far from their '
                 f'neighbours (sensor glitches: e.g. {abs(p[k]):.4g} W at {t[k]:.3f} s, the '
                 f'median {float(np.median(np.abs(p))):.3g} W) left out')
    return set(t[mask].tolist())


#: samples rebuilt per step of :func:`_stamp_ordered` (the order's indices as Python ints)
_ORDER_CHUNK = 65536


def _stamp_ordered(stores: dict[str, SampleColumns], order: dict[str, array.array]
                   ) -> Iterator[tuple[str, Any]]:
    """(topic, sample) of every stored sample in header-stamp order, ties in reading order,
    each sample rebuilt from its columns when it is reached."""
    topics = list(stores)
    parts = [(np.asarray(stores[t].column('t_s'), dtype=float),
              np.frombuffer(order[t], dtype=np.int64) if len(order[t])
              else np.zeros(0, dtype=np.int64)) for t in topics]
    t_all = np.concatenate([p[0] for p in parts])
    seq_all = np.concatenate([p[1] for p in parts])
    code = np.concatenate([np.full(len(stores[t]), k, dtype=np.int64)
                           for k, t in enumerate(topics)])
    row = np.concatenate([np.arange(len(stores[t]), dtype=np.int64) for t in topics])
    ranked = np.lexsort((seq_all, t_all))
    del t_all, seq_all
    for start in range(0, ranked.size, _ORDER_CHUNK):
        chunk = ranked[start:start + _ORDER_CHUNK]
        for k, r in zip(code[chunk].tolist(), row[chunk].tolist()):
            topic = topics[k]
            yield topic, stores[topic][r]


def _prepare_batteries(path: str | Path, samples: list[tuple[float, int, str, Any]],
                       notes: list[str]) -> list[tuple[float, int, str, Any]]:
    """The ``/battery_state`` samples through :func:`hexapod_common.battery.
    prepare_battery_samples` (milli-units scaled, several batteries summed or the one of
    ``--battery-source`` kept); one battery in V and A: ``samples`` unchanged. A stream that
    measures no power raises :class:`BagContentError`."""
    from hexapod_common.battery import prepare_battery_samples

    battery = [smp[3] for smp in samples if smp[2] == '/battery_state']
    try:
        combined, more = prepare_battery_samples(battery)
    except ValueError as err:
        raise BagContentError(f'bag {path}: {err}') from None
    notes.extend(more)
    if combined == battery:
        return samples
    rest = [smp for smp in samples if smp[2] != '/battery_state']
    n = len(samples)
    return rest + [(b.t_s, n + k, '/battery_state', b) for k, b in enumerate(combined)]


def _schedule_key(g: Any) -> tuple[Any, ...]:
    """What makes two /gait/phase samples the same walking schedule (not the phase): gait,
    legs, phase offsets, duty factor, period, step length and height. Compared with
    :func:`_same_schedule` (a gait node that recomputes its period every tick publishes
    values that differ in the last digits)."""
    return (g.gait, tuple(g.leg_names), tuple(float(x) for x in g.phase_offsets),
            float(g.duty_factor), float(g.period_s), float(g.step_length_m),
            float(g.step_height_m))


def _same_schedule(a: tuple[Any, ...] | None, b: tuple[Any, ...] | None,
                   rel: float = 1e-4) -> bool:
    if a is None or b is None:
        return False
    if a[0] != b[0] or a[1] != b[1] or len(a[2]) != len(b[2]):
        return False
    x = np.array(a[2] + a[3:], dtype=float)
    y = np.array(b[2] + b[3:], dtype=float)
    return bool(np.all(np.abs(x - y) <= rel * np.maximum(np.maximum(np.abs(x), np.abs(y)),
                                                         1.0)))


def _schedule_label(g: Any) -> str:
    return (f'{g.gait}, beta {g.duty_factor:g}, period {g.period_s:.4g} s, step '
            f'{g.step_length_m:g} m')


def _window_schedule(d: Any, changes: list[tuple[Any, ...]]) -> Any:
    """The /gait/phase sample of the one schedule in force over window ``d`` (standing,
    period 0, included: its windows are DescriptorAccumulator.STAND_WINDOW_S long), None when
    the schedule changes inside it."""
    t0, t1 = d.t_end_s - d.window_s, d.t_end_s
    times = [c[0] for c in changes]
    k0 = int(np.searchsorted(times, t0 + 1e-9, side='right')) - 1
    k1 = int(np.searchsorted(times, t1 - 1e-9, side='right')) - 1
    if k0 < 0:
        k0 = 0
    if not all(_same_schedule(changes[k][1], changes[k0][1]) for k in range(k0, k1 + 1)):
        return None
    if k1 < 0 or len(changes[k1]) < 4:
        return changes[k0][2]
    # the sample in force at the window's end: its settled values, not a later one's
    hist = changes[k1][3]
    j = int(np.searchsorted([h[1] for h in hist], t1 + 1e-9, side='right')) - 1
    return hist[max(j, 0)][2]


#: schedule samples kept per schedule: at most one per this long [s] (the latest of it)
SCHEDULE_HISTORY_S = 0.05


def _note_schedule_sample(hist: list[tuple[float, float, Any]], sample: Any) -> None:
    """Keep ``sample`` in a schedule's history ``[(bin start, sample time, sample)]``: a
    new entry when its values changed and the last entry is ``SCHEDULE_HISTORY_S`` old, else
    in place of the last entry when they changed (a gait node recomputing its period each
    tick keeps at most 20 entries a second; a steady one, one)."""
    start, _, last = hist[-1]
    if _schedule_key(sample) == _schedule_key(last):
        return
    if sample.t_s - start < SCHEDULE_HISTORY_S:
        hist[-1] = (start, sample.t_s, sample)
    else:
        hist.append((sample.t_s, sample.t_s, sample))


#: standing windows (1 s each) a stop needs to be a run of its own
MIN_STAND_WINDOWS = 3


def _schedule_segments(windows: list[Any], changes: list[tuple[Any, ...]]
                       ) -> list[tuple[Any, float, int, list[Any]]]:
    """Consecutive windows under one walking schedule: ``(gait sample, start [s], window
    count, windows)`` in time order; a schedule met again later is a new segment."""
    out: list[tuple[Any, float, int, list[Any]]] = []
    last_key = None
    for d in windows:
        g = _window_schedule(d, changes)
        if g is None:
            last_key = None
            continue
        key = _schedule_key(g)
        if not _same_schedule(key, last_key):
            out.append((g, float(d.t_end_s - d.window_s), 0, []))
            last_key = key
        _, t0, n, ws = out[-1]
        ws.append(d)
        # the segment's schedule: the one in force at its last window's end (settled)
        out[-1] = (g, t0, n + 1, ws)
    return out


def _joint_cycle_runs(path: str | Path, acc: Any, windows: list[Any],
                      joint_states: SampleColumns, notes: list[str],
                      custom: dict[str, str], has_effort: bool, speed_mps: float | None,
                      gait: Any) -> list[RobotRun]:
    """:class:`RobotRun` of each step period of a bag read on joint-derived cycles (see
    :func:`read_robot_bag`), in time order."""
    tracker = acc.tracker_
    if not windows:
        est = tracker.estimate_ if tracker is not None else None
        why = f'last estimate: {est.status}' + (f', autocorrelation peak {est.peak:.2f}'
                                                 if est is not None and
                                                 math.isfinite(est.peak) else '') \
            if est is not None else 'no joint positions'
        raise BagContentError(
            f'bag {path}: no whole gait cycle found from the joint positions ({why}; need a '
            'periodic gait, autocorrelation peak >= 0.5, over at least 3 periods, with '
            '/battery_state across it) and no /gait/phase to take the cycles from')
    notes.append('no /gait/phase: cycle boundaries from the joint positions (step period '
                 'by autocorrelation, hexapod_energy.cycles)')
    names = sorted({n for group in joint_states.distinct('names') for n in group})
    legs = sorted({n.rsplit('_', 1)[0] for n in names if '_' in n})
    sources = sorted({d.speed_source for d in windows})
    speed_source = sources[0] if len(sources) == 1 else '+'.join(sources)
    if speed_source == 'odometry':
        notes.append('speed from /odom (nav_msgs/Odometry position differenced over each '
                     'window, odometry frame)')
    elif speed_source == 'odometry_twist':
        notes.append(ODOM_TWIST_NOTE)
    elif speed_source == 'given':
        notes.append(f'speed {speed_mps} m/s as given (no /mocap/body or /odom)')
    elif 'none' in sources:
        n_none = sum(d.speed_source == 'none' for d in windows)
        notes.append('speed unknown (no /mocap/body, /odom or given speed) in '
                     f'{n_none} of {len(windows)} window(s): ' +
                     ('speed, cost of transport and specific resistance null'
                      if n_none == len(windows) else 'speed averaged over the others; cost of '
                      'transport and specific resistance over those windows'))
    if not has_effort:
        notes.append('no joint efforts (or efforts without velocities and positions): P_out '
                     'unknown (the Eq. 6 model needs the gait schedule)')
    groups = _period_groups(windows)
    # a transition's odd window or two is not a run of its own
    short = [g for g in groups if len(g) < MIN_PERIOD_WINDOWS]
    if short and len(short) < len(groups):
        groups = [g for g in groups if len(g) >= MIN_PERIOD_WINDOWS]
        notes.append(f'{sum(map(len, short))} window(s) between step periods left out')

    def run_of(k: int) -> RobotRun:
        wins = groups[k]
        seg_notes = list(notes)
        w = np.array([d.window_s for d in wins])
        period = float(w.sum()) / len(wins) / max(wins[0].cycles, 1)
        if len(groups) > 1:
            seg_notes.append(f'{len(groups)} step periods in this bag (the joints\' period '
                             f'changed by more than {PERIOD_CHANGE:.0%}): this run is number '
                             f'{k + 1} of {len(groups)} ({period:.4g} s, {len(wins)} window(s) '
                             f'from {wins[0].t_end_s - wins[0].window_s:.2f} s); each is its '
                             'own run')
        avg = lambda xs: float(np.sum(w * np.array(xs)) / np.sum(w))  # noqa: E731
        speeds = np.array([d.speed_mps for d in wins])
        known = np.isfinite(speeds)
        speed = float(np.sum(w[known] * speeds[known]) / np.sum(w[known])) if known.any() \
            else math.nan
        return RobotRun(
            path=str(path), windows=len(wins), window_s=float(w.sum()),
            power_in_w=avg([d.power_in_w for d in wins]),
            power_out_w=avg([d.power_out_w for d in wins]) if has_effort else math.nan,
            speed_mps=speed, gait=gait,
            payload_kg=_find_number(custom, ('payload_kg', 'payload')),
            current_sign=float(acc.sign_ or 0.0),
            extra={'custom_data': custom, 'notes': seg_notes, 'cycle_source': 'joints',
                   'speed_source': speed_source, 'period_s': period, 'leg_names': legs,
                   'joint_names': names, 'windows': list(wins),
                   'speed_span': speed_span(wins, has_effort),
                   'segment': {'index': k, 'of': len(groups),
                               't_start_s': float(wins[0].t_end_s - wins[0].window_s),
                               't_end_s': float(wins[-1].t_end_s)}},
        )

    return [run_of(k) for k in range(len(groups))]


#: relative change of the joint-derived step period that starts a new run
PERIOD_CHANGE = 0.10
#: fewest windows of one step period that make a run when the bag has longer ones
MIN_PERIOD_WINDOWS = 3


def _period_groups(windows: list[Any]) -> list[list[Any]]:
    """Consecutive joint-cycle windows of one step period: a window whose length differs from
    the median of the current group by more than :data:`PERIOD_CHANGE` starts a new one."""
    groups: list[list[Any]] = []
    for d in windows:
        if groups:
            ref = float(np.median([x.window_s for x in groups[-1]]))
            if abs(d.window_s - ref) <= PERIOD_CHANGE * ref:
                groups[-1].append(d)
                continue
        groups.append([d])
    return groups


#: a phase-label stream (tip, force, schedule) gap longer than this many of its median
#: intervals (and 50 ms) leaves the power samples in it out of the phase split
LABEL_GAP_INTERVALS = 5.0


def _far_from(t: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """True where ``t`` lies in a gap of the sorted stamps ``ref`` (an interval over
    :data:`LABEL_GAP_INTERVALS` times their median and 50 ms), or outside their span."""
    if ref.size < 3:
        return np.zeros(t.shape, dtype=bool)
    steps = np.diff(ref)
    limit = max(LABEL_GAP_INTERVALS * float(np.median(steps)), 0.05)
    k = np.searchsorted(ref, t)
    inside = (k > 0) & (k < ref.size)
    out = ~inside
    kk = np.clip(k, 1, ref.size - 1)
    out |= inside & (steps[kk - 1] > limit)
    return out


def _known_mean(weights: np.ndarray, values: list[float]) -> float:
    """Weighted mean of the finite ``values`` (NaN when none is)."""
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v)
    return float(np.sum(weights[ok] * v[ok]) / np.sum(weights[ok])) if ok.any() else math.nan


def speed_span(windows: list[Any], has_effort: bool) -> dict[str, Any] | None:
    """The windows whose speed is known, when only some are (motion capture over part of the
    run): their number, length and mean P_in and P_out [W], for the descriptors that divide
    by the speed (the cost of transport and the specific resistance), which are over those
    windows only. None when every window's speed is known, or none is.

    Before, the run's P_in over every window was divided by the speed of the tracked ones: a
    simulated EduBot jogging bag with motion capture over 8 of its 15 windows read 39.6 W over
    the bag (with its start) against 36.6 W over the tracked span that ``slip`` averages.
    """
    w = np.array([d.window_s for d in windows], dtype=float)
    known = np.isfinite(np.array([d.speed_mps for d in windows], dtype=float))
    if known.all() or not known.any():
        return None
    wk = w[known]

    def mean(xs: list[float]) -> float:
        return float(np.sum(wk * np.asarray(xs, dtype=float)[known]) / np.sum(wk))

    return {'windows': int(known.sum()), 'window_s': float(wk.sum()),
            'power_in_w': mean([d.power_in_w for d in windows]),
            'power_out_w': mean([d.power_out_w for d in windows]) if has_effort else math.nan}
