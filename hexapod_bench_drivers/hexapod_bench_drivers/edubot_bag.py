"""EduBot runs into rosbag2 bags, and the ``hexapod-sim edubot`` subcommand.

Topics (DESIGN §4); the proprioceptive topics are stamped and received at their sample time,
``/mocap/body`` is stamped in the mocap clock (sample time + ``time_offset``) and received at
its sample time (a clock offset moves the stamp only: the convention of :mod:`sim_bag`):

=================== ============================== =======  ===================================
topic               type                           rate     content
=================== ============================== =======  ===================================
``/joint_states``   sensor_msgs/JointState         100 Hz   ``<leg>_hip`` position (unwrapped)
                                                            [rad], velocity [rad/s], effort
                                                            [N m]
``/joint_commands`` sensor_msgs/JointState         100 Hz   Buehler-clock target position and
                                                            velocity
``/gait/phase``     hexapod_interfaces/GaitPhase   100 Hz   gait ``buehler``, period, duty
                                                            factor, sweep angle, leg offset,
                                                            slow-phase flags
``/battery_state``  sensor_msgs/BatteryState       100 Hz   voltage [V], current [A] negative
                                                            while discharging
``/mocap/body``     geometry_msgs/PoseStamped      120 Hz   COM pose in frame ``mocap``, mocap
                                                            clock, only inside the volume
=================== ============================== =======  ===================================

Custom metadata: ``hexapod_sim.effects`` (JSON ``{name: {value, unit}}`` of the effects that are
on, the format of :mod:`effects`) and ``hexapod_sim.edubot_truth`` (JSON of
:attr:`EdubotRun.truth`: stance windows, frame transform, clock offset). No topic carries truth.
"""

from __future__ import annotations

import argparse
import json
import math
import struct
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hexapod_common.cli_args import NumberArgumentParser
from hexapod_bench_drivers import sim_cdr as cdr
from hexapod_bench_drivers.edubot_sim import (
    EDUBOT_EFFECTS,
    MAX_DURATION_S,
    EdubotParams,
    EdubotRun,
    EdubotSimError,
    resolve_effects,
    simulate_edubot,
)

__all__ = [
    'EFFECTS_KEY',
    'TRUTH_KEY',
    'add_cli',
    'effects_json',
    'main',
    'parse_effect_args',
    'write_edubot_bag',
    'write_run',
]

EFFECTS_KEY = 'hexapod_sim.effects'
TRUTH_KEY = 'hexapod_sim.edubot_truth'
#: Most runs of one ``--runs``.
MAX_RUNS = 1000


def effects_json(effects: Mapping[str, float]) -> str:
    """JSON of the effects that are on (value != 0) with their units."""
    return json.dumps({name: {'value': value, 'unit': EDUBOT_EFFECTS[name].unit}
                       for name, value in sorted(effects.items()) if value != 0},
                      sort_keys=True)


_STAMP = struct.Struct('<iI')
_F32 = struct.Struct('<f')
_F64 = struct.Struct('<d')
_POSE = struct.Struct('<7d')


def _patch_stamp(buf: bytearray, t_ns: int) -> None:
    _STAMP.pack_into(buf, 4, int(t_ns // 1_000_000_000), int(t_ns % 1_000_000_000))


class _BatteryTemplate:
    """sensor_msgs/msg/BatteryState of the EduBot's 4S LiPo, encoded once and patched.

    Discharging, health good, LiPo, present, design capacity 1.32 Ah, four cell voltages of
    ``voltage_v / 4``, location ``edubot``; unknown fields NaN.
    """

    def __init__(self) -> None:
        nan = math.nan
        b = cdr.CdrBuffer()
        b.header(0, '')
        b.align(4)
        self.off_v = 4 + b.pos
        b.pack('fffffff', 4, 0.0, nan, 0.0, nan, nan, 1.32, nan)
        b.pack('BBB?', 1, 2, 1, 3, True)     # DISCHARGING, GOOD, LIPO, present
        b.pack('I', 4, 4)
        self.off_cells = 4 + b.pos
        b.raw(bytes(16))
        b.array((), 'f4')
        b.string('edubot')
        b.string('')
        self.buf = bytearray(b.bytes())

    def encode(self, t_ns: int, voltage_v: float, current_a: float) -> bytes:
        buf = bytearray(self.buf)
        _patch_stamp(buf, t_ns)
        _F32.pack_into(buf, self.off_v, voltage_v)
        _F32.pack_into(buf, self.off_v + 8, current_a)
        buf[self.off_cells:self.off_cells + 16] = np.full(
            4, voltage_v / 4, dtype='<f4').tobytes()
        return bytes(buf)


class _GaitPhaseTemplate:
    """hexapod_interfaces/msg/GaitPhase of one Buehler clock, encoded once and patched.

    The layout is fixed for a clock (strings and array lengths do not change), so only the
    stamp, ``cycle_phase``, ``in_stance`` and ``supporting_legs`` are written per message.
    """

    def __init__(self, clock: Any, leg_names: list[str], offsets: np.ndarray) -> None:
        b = cdr.CdrBuffer()
        b.header(0, '')
        b.string('buehler')
        b.pack('dddddd', 8, float(clock.period_s), float(clock.duty_factor), 0.0, 0.0,
               float(clock.sweep_angle_rad), float(clock.leg_offset_rad))
        b.align(8)
        self.off_phase = 4 + b.pos
        b.pack('d', 8, 0.0)
        b.strings(leg_names)
        b.array(offsets, 'f8')
        b.pack('I', 4, len(leg_names))
        self.off_stance = 4 + b.pos
        self.n = len(leg_names)
        b.raw(bytes(self.n))
        self.off_support = 4 + b.pos
        b.pack('B', 1, 0)
        self.buf = bytearray(b.bytes())

    def encode(self, t_ns: int, cycle_phase: float, in_stance: np.ndarray,
               supporting: int) -> bytes:
        buf = bytearray(self.buf)
        _patch_stamp(buf, t_ns)
        _F64.pack_into(buf, self.off_phase, cycle_phase)
        buf[self.off_stance:self.off_stance + self.n] = \
            np.asarray(in_stance, dtype=bool).view(np.uint8).tobytes()
        buf[self.off_support] = supporting
        return bytes(buf)


class _PoseTemplate:
    """geometry_msgs/msg/PoseStamped in one frame, encoded once and patched."""

    def __init__(self, frame_id: str) -> None:
        b = cdr.CdrBuffer()
        b.header(0, frame_id)
        b.align(8)
        self.off = 4 + b.pos
        b.raw(bytes(56))
        self.buf = bytearray(b.bytes())

    def encode(self, t_ns: int, position_m: np.ndarray, quat_xyzw: np.ndarray) -> bytes:
        buf = bytearray(self.buf)
        _patch_stamp(buf, t_ns)
        _POSE.pack_into(buf, self.off, *position_m.tolist(), *quat_xyzw.tolist())
        return bytes(buf)


def write_run(path: str | Path, run: EdubotRun, *, storage: str = 'mcap') -> Path:
    """Write an already simulated run into a new bag at ``path``; returns the path.

    Messages are encoded by the fast CDR encoders of :mod:`sim_cdr` and the templates above, which
    write the bytes rosbags' serializer writes (checked in ``test_edubot_bag.py``).
    """
    from hexapod_common.bags import BagWriter

    path = Path(path)
    names = [f'{leg}_hip' for leg in run.leg_names]
    clock = run.clock
    js_t, bat_t = 'sensor_msgs/msg/JointState', 'sensor_msgs/msg/BatteryState'
    phase_t, pose_t = 'hexapod_interfaces/msg/GaitPhase', 'geometry_msgs/msg/PoseStamped'
    with BagWriter(path, storage=storage) as w:
        w.set_custom_data(EFFECTS_KEY, effects_json(run.effects))
        w.set_custom_data(TRUTH_KEY, json.dumps(run.truth, sort_keys=True))
        slow_l = clock.in_slow_phase(run.t_s, 'left') if hasattr(clock, 'in_slow_phase') \
            else np.zeros(run.t_s.shape, dtype=bool)
        slow_r = clock.in_slow_phase(run.t_s, 'right') if hasattr(clock, 'in_slow_phase') \
            else np.zeros(run.t_s.shape, dtype=bool)
        left_leg = np.array([leg in ('L1', 'R2', 'L3') for leg in run.leg_names])
        offsets = np.where(left_leg, 0.0, 0.5)
        in_stance = np.where(left_leg[None, :], slow_l[:, None], slow_r[:, None])
        supporting = in_stance.sum(axis=1)
        period = float(clock.period_s)
        legs = list(run.leg_names)
        pos, vel, eff = run.hip_position_rad, run.hip_velocity_rad_s, run.hip_effort_nm
        tpos, tvel = run.target_position_rad, run.target_velocity_rad_s
        volt, cur = run.battery_voltage_v, run.battery_current_a
        m_pos, m_quat = run.mocap_position_m, run.mocap_quat_xyzw
        battery = _BatteryTemplate()
        phase = _GaitPhaseTemplate(clock, legs, offsets)
        pose = _PoseTemplate('mocap')
        cycle = (run.t_s / period) % 1.0
        # mocap: stamped in its own clock (true time + time_offset), received by the recorder
        # at the true sample time (a clock offset, no transport delay; see sim_bag)
        m_offset = float(run.effects.get('time_offset', 0.0))
        events = sorted(
            [(int(round(t * 1e9)), k, 'p') for k, t in enumerate(run.t_s)]
            + [(int(round((t - m_offset) * 1e9)), k, 'm')
               for k, t in enumerate(run.mocap_t_s) if t >= 0])
        for t_ns, k, kind in events:
            if kind == 'm':
                stamp_ns = int(round(float(run.mocap_t_s[k]) * 1e9))
                w.write('/mocap/body', pose_t,
                        pose.encode(stamp_ns, m_pos[k], m_quat[k]), t_ns)
                continue
            w.write('/joint_states', js_t,
                    cdr.joint_state(t_ns, names, pos[k], vel[k], eff[k]), t_ns)
            w.write('/joint_commands', js_t,
                    cdr.joint_state(t_ns, names, tpos[k], tvel[k], ()), t_ns)
            w.write('/gait/phase', phase_t, phase.encode(
                t_ns, float(cycle[k]), in_stance[k], int(supporting[k])), t_ns)
            w.write('/battery_state', bat_t,
                    battery.encode(t_ns, float(volt[k]), float(cur[k])), t_ns)
    return path


def write_edubot_bag(path: str | Path, gait: Any, *, duration_s: float,
                     effects: Mapping[str, float] | None = None, seed: int = 0,
                     storage: str = 'mcap', params: EdubotParams = EdubotParams()) -> Path:
    """Simulate one EduBot run (:func:`simulate_edubot`) and write it into a bag at ``path``."""
    run = simulate_edubot(gait, duration_s=duration_s, effects=effects, seed=seed,
                          params=params)
    return write_run(path, run, storage=storage)


def parse_effect_args(items: list[str] | None) -> dict[str, float]:
    """``['leg_damping=20', 'mocap_noise=0']`` -> dict; refuses unknown names and bad values."""
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition('=')
        name = name.strip()
        if not sep:
            raise EdubotSimError(f'--effect {item!r}: expected NAME=VALUE')
        if name not in EDUBOT_EFFECTS:
            raise EdubotSimError(f'--effect {item!r}: unknown effect {name!r}; expected one '
                                 f'of {sorted(EDUBOT_EFFECTS)}')
        try:
            out[name] = float(value)
        except ValueError as err:
            raise EdubotSimError(f'--effect {item!r}: value {value!r} is not a number') from err
    return out


def _effects_help() -> str:
    return '; '.join(f'{e.name} [{e.unit}] default {e.default:g}: {e.doc}'
                     for e in EDUBOT_EFFECTS.values())


def add_cli(subparsers: Any) -> None:
    """Register ``edubot``: ``hexapod-sim edubot --out BAG [--gait G] [--duration S]
    [--effect NAME=VALUE ...] [--seed N] [--runs N] [--storage mcap|sqlite3]``."""
    p = subparsers.add_parser(
        'edubot', help='RHex-class EduBot runs (Komsuoglu et al.) into bags',
        description='Simulate straight EduBot runs through a motion-capture volume and write '
                    '/joint_states, /joint_commands, /gait/phase, /battery_state and '
                    '/mocap/body into a rosbag2 bag. With --runs N > 1, OUT is a folder '
                    'holding run_000, run_001, ... (seeds SEED, SEED+1, ...).')
    p.add_argument('--out', required=True, help='bag folder to create (must not exist)')
    p.add_argument('--gait', default='running', choices=['running', 'jogging', 'pace', 'walk'],
                   help='Table 1 gait (default running)')
    p.add_argument('--duration', type=float, default=6.0,
                   help=f'simulated seconds per run, 0.02 to {MAX_DURATION_S:g} (default 6)')
    p.add_argument('--effect', action='append', metavar='NAME=VALUE',
                   help='set an effect (repeatable; 0 = off). ' + _effects_help())
    p.add_argument('--seed', type=int, default=0,
                   help='random seed (default 0; same seed, same bag). It changes the '
                        'physics, not only the noise: it draws the battery\'s '
                        'open-circuit voltage (15.6 +- 0.2 V) and the initial speed '
                        '(+-10 %%), which pick the gait\'s mode where it has two '
                        '(pace: 24 or 28 W), as well as the mocap frame and noise')
    p.add_argument('--runs', type=int, default=1,
                   help=f'number of runs, 1 to {MAX_RUNS} (default 1)')
    p.add_argument('--storage', default='mcap', choices=['mcap', 'sqlite3'])
    p.set_defaults(func=_run_cli)


def _check_cli(args: argparse.Namespace) -> str | None:
    """Why ``args`` cannot give a run, naming the option, else None (before simulating)."""
    params = EdubotParams()
    duration = args.duration
    if not (math.isfinite(duration) and duration > 0):
        return f'--duration must be a finite number > 0 s, got {duration:g}'
    if duration * params.proprio_rate_hz < 2:
        return (f'--duration {duration:g} s holds fewer than 2 samples at '
                f'{params.proprio_rate_hz:g} Hz: at least {2 / params.proprio_rate_hz:g} s')
    if duration > MAX_DURATION_S:
        return (f'--duration {duration:g} s is more than {MAX_DURATION_S:g} s (a run crosses '
                'the 2 m tracking volume in seconds; 600 s take about 0.3 GB of memory)')
    if not 1 <= args.runs <= MAX_RUNS:
        return f'--runs must be from 1 to {MAX_RUNS}, got {args.runs}'
    if args.seed < 0:
        return f'--seed must be >= 0, got {args.seed}'
    return None


def _run_cli(args: argparse.Namespace) -> int:
    import sys

    from hexapod_common.jsondoc import json_safe

    try:
        if reason := _check_cli(args):
            raise EdubotSimError(reason)
        effects = parse_effect_args(args.effect)
        try:
            resolve_effects(effects)
        except EdubotSimError as err:
            raise EdubotSimError(f'--effect: {err}') from None
        out = Path(args.out)
        if out.exists():
            raise EdubotSimError(f'--out {out} exists; refusing to overwrite')
        targets = [out] if args.runs == 1 else \
            [out / f'run_{i:03d}' for i in range(args.runs)]
        if args.runs > 1:
            out.mkdir(parents=True)
        try:
            from tqdm import tqdm
            from hexapod_common.progress import bar_options
            iterator: Any = tqdm(list(enumerate(targets)), desc='edubot runs', unit='run',
                                 **bar_options(len(targets) < 2))
        except ImportError:  # pragma: no cover
            iterator = enumerate(targets)
        for i, target in iterator:
            run = simulate_edubot(args.gait, duration_s=args.duration, effects=effects,
                                  seed=args.seed + i)
            write_run(target, run, storage=args.storage)
            summ = run.truth.get('summary', {})
            # strict JSON: a stalled run has no speed, its specific resistance is null, not
            # Infinity
            print(json.dumps(json_safe({'bag': str(target), 'gait': args.gait,
                                        'seed': args.seed + i, 'duration_s': args.duration,
                                        **summ})))
    except EdubotSimError as err:
        print(f'hexapod-sim edubot: error: {err}', file=sys.stderr)
        return 2
    return 0


def main(argv: list[str] | None = None) -> int:
    """Standalone entry (same as ``hexapod-sim edubot``)."""
    parser = NumberArgumentParser(prog='hexapod-sim')
    sub = parser.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = parser.parse_args(argv)
    return int(args.func(args))
