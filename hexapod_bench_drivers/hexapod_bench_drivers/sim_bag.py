"""Write a simulator's :class:`~.sim_core.SimTrace` into a rosbag2 bag as the real drivers' topics.

Topics (DESIGN section 4): ``/joint_states``, ``/joint_commands``, ``/gait/phase`` (every sample),
``/servo_status`` (every ``status_every`` samples), ``/battery_state`` (every sample, ROS sign:
current negative while discharging), and for the bench ``/bench/ground_force``,
``/bench/leg_tip`` and ``/bench/session`` (one message per state change). ``header.stamp`` is the
time a stream's device stamps (``time_offset`` and ``sensor_latency`` effects shift it); the bag
time is the true sample time. The effect set goes into the bag's metadata only
(custom data ``hexapod_sim.effects``), with the run's configuration under ``hexapod_sim.config``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from os import PathLike
from typing import Any

import numpy as np

from hexapod_common.bags import BagWriter

from .effects import METADATA_KEY
from .sim_core import SimTrace

__all__ = ['CONFIG_KEY', 'DEFAULT_START_NS', 'write_trace']

#: Custom-data key of the run's configuration (JSON) in the bag's metadata.
CONFIG_KEY = 'hexapod_sim.config'
#: Bag time of the simulation's t = 0 (fixed, so that the same seed gives the same bag).
DEFAULT_START_NS = 1_700_000_000_000_000_000


class _Msgs:
    """Direct constructors of the rosbags message classes (faster than generic builders)."""

    def __init__(self, store: Any) -> None:
        t = store.types
        self.Time = t['builtin_interfaces/msg/Time']
        self.Header = t['std_msgs/msg/Header']
        self.JointState = t['sensor_msgs/msg/JointState']
        self.BatteryState = t['sensor_msgs/msg/BatteryState']
        self.Wrench = t['geometry_msgs/msg/Wrench']
        self.WrenchStamped = t['geometry_msgs/msg/WrenchStamped']
        self.Vector3 = t['geometry_msgs/msg/Vector3']
        self.Point = t['geometry_msgs/msg/Point']
        self.PointStamped = t['geometry_msgs/msg/PointStamped']
        self.GaitPhase = t['hexapod_interfaces/msg/GaitPhase']
        self.ServoStatus = t['hexapod_interfaces/msg/ServoStatus']
        self.BenchSession = t['hexapod_interfaces/msg/BenchSession']

    def header(self, t_ns: int, frame_id: str = '') -> Any:
        return self.Header(stamp=self.Time(sec=int(t_ns // 1_000_000_000),
                                           nanosec=int(t_ns % 1_000_000_000)),
                           frame_id=frame_id)


def write_trace(trace: SimTrace, path: str | PathLike[str], *, storage: str = 'mcap',
                start_time_ns: int = DEFAULT_START_NS, status_every: int = 10,
                seed: int | None = None, progress: Callable[[int], None] | None = None
                ) -> dict[str, int]:
    """Write ``trace`` into a new bag at ``path``; returns the message count per topic."""
    with BagWriter(path, storage=storage) as writer:
        writer.set_custom_data(METADATA_KEY, trace.effects_json)
        config = dict(trace.config)
        if seed is not None:
            config['seed'] = seed
        writer.set_custom_data(CONFIG_KEY, json.dumps(config, sort_keys=True, default=str))
        _write(writer, trace, start_time_ns, status_every, progress)
        return dict(writer.counts)


def _ns(start_ns: int, t_s: float) -> int:
    return start_ns + int(round(t_s * 1e9))


def _write(w: BagWriter, tr: SimTrace, start_ns: int, status_every: int,
           progress: Callable[[int], None] | None) -> None:
    m = _Msgs(w.types)
    names = list(tr.joint_names)
    legs = list(tr.leg_names)
    offsets = np.asarray(tr.phase_offsets, dtype=np.float64)
    empty = np.zeros(0, dtype=np.float64)
    sessions = sorted(tr.sessions, key=lambda r: r.t_s)
    si = 0
    js_t, bat_t = 'sensor_msgs/msg/JointState', 'sensor_msgs/msg/BatteryState'
    for k in range(tr.sample_count):
        t = float(tr.t_s[k])
        t_ns = _ns(start_ns, t)
        while si < len(sessions) and sessions[si].t_s <= t:
            r = sessions[si]
            rec_ns = _ns(start_ns, r.t_s)
            w.write('/bench/session', 'hexapod_interfaces/msg/BenchSession', m.BenchSession(
                header=m.header(rec_ns, 'bench'), session_id=r.session_id, state=r.state,
                load_mass=float(r.load_mass_kg), frequency=float(r.frequency_hz),
                duty_factor=float(r.duty_factor), step_length=float(r.step_length_m),
                step_height=float(r.step_height_m)), rec_ns)
            si += 1
        servo_ns = _ns(start_ns, t + tr.servo_stamp_offset_s)
        w.write('/joint_states', js_t, m.JointState(
            header=m.header(servo_ns), name=names,
            position=np.asarray(tr.position_rad[k], dtype=np.float64),
            velocity=np.asarray(tr.velocity_rad_s[k], dtype=np.float64),
            effort=np.asarray(tr.effort_nm[k], dtype=np.float64)), t_ns)
        w.write('/joint_commands', js_t, m.JointState(
            header=m.header(t_ns), name=names,
            position=np.asarray(tr.command_position_rad[k], dtype=np.float64),
            velocity=np.asarray(tr.command_velocity_rad_s[k], dtype=np.float64),
            effort=empty), t_ns)
        period = float(tr.period_s[k])
        w.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase', m.GaitPhase(
            header=m.header(t_ns), gait=str(tr.gait_name[k]), period=period,
            duty_factor=float(tr.duty_factor[k]), step_length=float(tr.step_length_m[k]),
            step_height=float(tr.step_height_m[k]), sweep_angle=0.0, leg_offset=0.0,
            cycle_phase=float(tr.cycle_phase[k]), leg_names=legs, phase_offsets=offsets,
            in_stance=np.asarray(tr.in_stance[k], dtype=bool),
            supporting_legs=int(tr.supporting_legs[k])), t_ns)
        if k % status_every == 0:
            w.write('/servo_status', 'hexapod_interfaces/msg/ServoStatus', m.ServoStatus(
                header=m.header(servo_ns), name=names,
                temperature=np.asarray(tr.temperature_c[k], dtype=np.float32),
                voltage=np.asarray(tr.servo_voltage_v[k], dtype=np.float32),
                load=np.asarray(tr.load_fraction[k], dtype=np.float32),
                error=np.asarray(tr.servo_error[k], dtype=np.uint8)), servo_ns)
        bat_ns = _ns(start_ns, t + tr.battery_stamp_offset_s)
        w.write('/battery_state', bat_t, m.BatteryState(
            header=m.header(bat_ns, 'supply'), voltage=float(tr.battery_voltage_v[k]),
            temperature=math.nan, current=float(tr.battery_current_a[k]), charge=math.nan,
            capacity=math.nan, design_capacity=math.nan, percentage=math.nan,
            power_supply_status=2 if tr.powered[k] else 3, power_supply_health=1,
            power_supply_technology=3, present=True,
            cell_voltage=np.zeros(0, dtype=np.float32),
            cell_temperature=np.zeros(0, dtype=np.float32), location='', serial_number=''),
            t_ns)
        if tr.ground_force_n is not None and tr.tip_m is not None:
            w.write('/bench/ground_force', 'geometry_msgs/msg/WrenchStamped', m.WrenchStamped(
                header=m.header(t_ns, 'bench'), wrench=m.Wrench(
                    force=m.Vector3(x=0.0, y=0.0, z=float(tr.ground_force_n[k])),
                    torque=m.Vector3(x=0.0, y=0.0, z=0.0))), t_ns)
            w.write('/bench/leg_tip', 'geometry_msgs/msg/PointStamped', m.PointStamped(
                header=m.header(t_ns, 'bench'), point=m.Point(
                    x=float(tr.tip_m[k, 0]), y=float(tr.tip_m[k, 1]),
                    z=float(tr.tip_m[k, 2]))), t_ns)
        if progress is not None and k % 1000 == 999:
            progress(1000)
    while si < len(sessions):
        r = sessions[si]
        rec_ns = _ns(start_ns, r.t_s)
        w.write('/bench/session', 'hexapod_interfaces/msg/BenchSession', m.BenchSession(
            header=m.header(rec_ns, 'bench'), session_id=r.session_id, state=r.state,
            load_mass=float(r.load_mass_kg), frequency=float(r.frequency_hz),
            duty_factor=float(r.duty_factor), step_length=float(r.step_length_m),
            step_height=float(r.step_height_m)), rec_ns)
        si += 1
