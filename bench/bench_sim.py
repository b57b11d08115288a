"""Benchmark of the batch simulators: real-time factor of `hexapod-sim`-style runs into bags.

Prints, for the servo hexapod (18 AX-18A, 0.6 m/s tripod, 100 Hz) and a bench plan, the
simulated seconds per wall second of physics alone and of physics plus bag writing (target:
>= 20x real time). Baseline measured in the same run: the same trace written with rosbags'
generic message classes and ``serialize_cdr`` instead of the simulators' cached CDR encoders,
and the physics with the servo model's numpy sub-step loop instead of its compiled one.

    .venv/bin/python bench/bench_sim.py [--duration 20]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.servo_model import ServoModel
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.bags import BagWriter, new_msg, stamp


def baseline_write(trace, path: Path) -> None:
    """Straightforward writer: generic rosbags messages, three high-rate topics."""
    names = list(trace.joint_names)
    with BagWriter(path) as w:
        for k in range(trace.sample_count):
            t_ns = 1_700_000_000_000_000_000 + int(round(trace.t_s[k] * 1e9))
            w.write('/joint_states', 'sensor_msgs/msg/JointState', new_msg(
                'sensor_msgs/msg/JointState', header=stamp(t_ns), name=names,
                position=trace.position_rad[k], velocity=trace.velocity_rad_s[k],
                effort=trace.effort_nm[k]), t_ns)
            w.write('/joint_commands', 'sensor_msgs/msg/JointState', new_msg(
                'sensor_msgs/msg/JointState', header=stamp(t_ns), name=names,
                position=trace.command_position_rad[k],
                velocity=trace.command_velocity_rad_s[k]), t_ns)
            w.write('/battery_state', 'sensor_msgs/msg/BatteryState', new_msg(
                'sensor_msgs/msg/BatteryState', header=stamp(t_ns),
                voltage=float(trace.battery_voltage_v[k]),
                current=float(trace.battery_current_a[k]), temperature=math.nan,
                present=True), t_ns)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--duration', type=float, default=20.0, help='simulated robot time [s]')
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix='bench_sim_'))

    simulate_robot(0.1)      # warm: imports and the compiled servo loop loaded
    t0 = time.perf_counter()
    trace = simulate_robot(args.duration, RobotConfig(speed_mps=0.6))
    t_sim = time.perf_counter() - t0
    ServoModel.compiled = False          # baseline: the numpy sub-step loop
    t0 = time.perf_counter()
    simulate_robot(args.duration, RobotConfig(speed_mps=0.6))
    t_sim_np = time.perf_counter() - t0
    ServoModel.compiled = True
    t0 = time.perf_counter()
    counts = write_trace(trace, tmp / 'robot')
    t_bag = time.perf_counter() - t0
    t0 = time.perf_counter()
    baseline_write(trace, tmp / 'robot_baseline')
    t_base = time.perf_counter() - t0
    sim_s = args.duration
    n_msgs = sum(counts.values())
    print(f'robot (18 servos, 100 Hz, {sim_s:g} s simulated, {n_msgs} messages)')
    print(f'  physics only        : {sim_s / t_sim:7.1f} x real time   baseline (numpy '
          f'servo loop): {sim_s / t_sim_np:7.1f} x   ratio {t_sim_np / t_sim:.2f}x')
    print(f'  physics + bag       : {sim_s / (t_sim + t_bag):7.1f} x real time  (target >= 20)')
    print(f'  bag writer          : {n_msgs / t_bag:9.0f} msg/s   baseline (rosbags generic, '
          f'3 of 5 topics): {3 * trace.sample_count / t_base:9.0f} msg/s   ratio '
          f'{(n_msgs / t_bag) / (3 * trace.sample_count / t_base):.1f}x')

    plan = BenchPlan(loads_kg=(0.0, 0.515), frequencies_hz=(0.0, 1.0, 3.0),
                     walk_s=args.duration / 2, max_cool_s=600.0)
    t0 = time.perf_counter()
    btrace = simulate_bench(plan)
    t_bsim = time.perf_counter() - t0
    t0 = time.perf_counter()
    bcounts = write_trace(btrace, tmp / 'bench')
    t_bbag = time.perf_counter() - t0
    span = float(btrace.t_s[-1])
    walking = float(np.sum(btrace.powered)) / 100.0
    print(f'bench plan (6 sessions, {walking:.0f} s powered at 100 Hz, {span:.0f} s timeline '
          f'with cooling, {sum(bcounts.values())} messages)')
    print(f'  timeline + bag      : {span / (t_bsim + t_bbag):7.1f} x real time')
    print(f'  powered part + bag  : {walking / (t_bsim + t_bbag):7.1f} x real time')


if __name__ == '__main__':
    main()
