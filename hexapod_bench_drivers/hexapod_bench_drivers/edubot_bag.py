"""EduBot runs into rosbag2 bags, and the ``hexapod-sim edubot`` subcommand.

Topics (DESIGN §4), stamps = bag times:

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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hexapod_bench_drivers.edubot_sim import (
    EDUBOT_EFFECTS,
    EdubotParams,
    EdubotRun,
    EdubotSimError,
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


def effects_json(effects: Mapping[str, float]) -> str:
    """JSON of the effects that are on (value != 0) with their units."""
    return json.dumps({name: {'value': value, 'unit': EDUBOT_EFFECTS[name].unit}
                       for name, value in sorted(effects.items()) if value != 0},
                      sort_keys=True)


def _stamp(types: Any, t_ns: int) -> Any:
    return types['builtin_interfaces/msg/Time'](sec=int(t_ns // 1_000_000_000),
                                                nanosec=int(t_ns % 1_000_000_000))


def write_run(path: str | Path, run: EdubotRun, *, storage: str = 'mcap') -> Path:
    """Write an already simulated run into a new bag at ``path``; returns the path."""
    from hexapod_common.bags import BagWriter

    path = Path(path)
    names = [f'{leg}_hip' for leg in run.leg_names]
    clock = run.clock
    with BagWriter(path, storage=storage) as w:
        types = w.types.types
        header_t = types['std_msgs/msg/Header']
        joint_t = types['sensor_msgs/msg/JointState']
        batt_t = types['sensor_msgs/msg/BatteryState']
        pose_t = types['geometry_msgs/msg/PoseStamped']
        posep_t = types['geometry_msgs/msg/Pose']
        point_t = types['geometry_msgs/msg/Point']
        quat_t = types['geometry_msgs/msg/Quaternion']
        phase_t = types['hexapod_interfaces/msg/GaitPhase']
        w.set_custom_data(EFFECTS_KEY, effects_json(run.effects))
        w.set_custom_data(TRUTH_KEY, json.dumps(run.truth, sort_keys=True))
        empty = np.zeros(0)
        slow_l = clock.in_slow_phase(run.t_s, 'left') if hasattr(clock, 'in_slow_phase') \
            else np.zeros(run.t_s.shape, dtype=bool)
        slow_r = clock.in_slow_phase(run.t_s, 'right') if hasattr(clock, 'in_slow_phase') \
            else np.zeros(run.t_s.shape, dtype=bool)
        left_leg = np.array([leg in ('L1', 'R2', 'L3') for leg in run.leg_names])
        offsets = np.where(left_leg, 0.0, 0.5)
        proprio = sorted(
            [(int(round(t * 1e9)), k, 'p') for k, t in enumerate(run.t_s)]
            + [(int(round(t * 1e9)), k, 'm') for k, t in enumerate(run.mocap_t_s) if t >= 0])
        for t_ns, k, kind in proprio:
            stamp = _stamp(types, t_ns)
            if kind == 'm':
                pos = run.mocap_position_m[k]
                q = run.mocap_quat_xyzw[k]
                msg = pose_t(header=header_t(stamp=stamp, frame_id='mocap'),
                             pose=posep_t(position=point_t(x=float(pos[0]), y=float(pos[1]),
                                                           z=float(pos[2])),
                                          orientation=quat_t(x=float(q[0]), y=float(q[1]),
                                                             z=float(q[2]), w=float(q[3]))))
                w.write('/mocap/body', 'geometry_msgs/msg/PoseStamped', msg, t_ns)
                continue
            hdr = header_t(stamp=stamp, frame_id='')
            w.write('/joint_states', 'sensor_msgs/msg/JointState', joint_t(
                header=hdr, name=names, position=run.hip_position_rad[k].copy(),
                velocity=run.hip_velocity_rad_s[k].copy(),
                effort=run.hip_effort_nm[k].copy()), t_ns)
            w.write('/joint_commands', 'sensor_msgs/msg/JointState', joint_t(
                header=hdr, name=names, position=run.target_position_rad[k].copy(),
                velocity=run.target_velocity_rad_s[k].copy(), effort=empty), t_ns)
            in_stance = np.where(left_leg, slow_l[k], slow_r[k])
            w.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase', phase_t(
                header=hdr, gait='buehler', period=float(clock.period_s),
                duty_factor=float(clock.duty_factor), step_length=0.0, step_height=0.0,
                sweep_angle=float(clock.sweep_angle_rad),
                leg_offset=float(clock.leg_offset_rad),
                cycle_phase=float((run.t_s[k] / clock.period_s) % 1.0),
                leg_names=list(run.leg_names), phase_offsets=offsets,
                in_stance=in_stance.astype(bool),
                supporting_legs=int(in_stance.sum())), t_ns)
            w.write('/battery_state', 'sensor_msgs/msg/BatteryState', batt_t(
                header=hdr, voltage=float(run.battery_voltage_v[k]), temperature=math.nan,
                current=float(run.battery_current_a[k]), charge=math.nan, capacity=math.nan,
                design_capacity=1.32, percentage=math.nan,
                power_supply_status=2,         # DISCHARGING
                power_supply_health=1,         # GOOD
                power_supply_technology=3,     # LIPO
                present=True, cell_voltage=np.full(4, float(run.battery_voltage_v[k]) / 4,
                                                   dtype=np.float32),
                cell_temperature=np.zeros(0, dtype=np.float32), location='edubot',
                serial_number=''), t_ns)
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
                   help='simulated seconds per run (default 6)')
    p.add_argument('--effect', action='append', metavar='NAME=VALUE',
                   help='set an effect (repeatable; 0 = off). ' + _effects_help())
    p.add_argument('--seed', type=int, default=0, help='random seed (default 0)')
    p.add_argument('--runs', type=int, default=1, help='number of runs (default 1)')
    p.add_argument('--storage', default='mcap', choices=['mcap', 'sqlite3'])
    p.set_defaults(func=_run_cli)


def _run_cli(args: argparse.Namespace) -> int:
    import sys

    try:
        effects = parse_effect_args(args.effect)
        if args.runs < 1:
            raise EdubotSimError(f'--runs must be >= 1, got {args.runs}')
        out = Path(args.out)
        if out.exists():
            raise EdubotSimError(f'--out {out} exists; refusing to overwrite')
        targets = [out] if args.runs == 1 else \
            [out / f'run_{i:03d}' for i in range(args.runs)]
        if args.runs > 1:
            out.mkdir(parents=True)
        try:
            from tqdm import tqdm
            iterator: Any = tqdm(list(enumerate(targets)), desc='edubot runs', unit='run',
                                 disable=len(targets) < 2)
        except ImportError:  # pragma: no cover
            iterator = enumerate(targets)
        for i, target in iterator:
            run = simulate_edubot(args.gait, duration_s=args.duration, effects=effects,
                                  seed=args.seed + i)
            write_run(target, run, storage=args.storage)
            summ = run.truth.get('summary', {})
            print(json.dumps({'bag': str(target), 'gait': args.gait, 'seed': args.seed + i,
                              'duration_s': args.duration, **summ}))
    except EdubotSimError as err:
        print(f'hexapod-sim edubot: error: {err}', file=sys.stderr)
        return 2
    return 0


def main(argv: list[str] | None = None) -> int:
    """Standalone entry (same as ``hexapod-sim edubot``)."""
    parser = argparse.ArgumentParser(prog='hexapod-sim')
    sub = parser.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = parser.parse_args(argv)
    return int(args.func(args))
