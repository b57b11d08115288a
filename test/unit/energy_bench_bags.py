"""Small synthetic single-leg bench bags for the energy tests (rosbags only, no ROS).

One bag per session (no ``/bench/session``: ``energy --bench-sessions``), its power piecewise
constant by the commanded phase (an outside review's design):

* P_stance = 1.5 + 4.0 m + 0.8 / T_stance, P_swing = 1.0 + 0.5 m + 1.2 / T_swing,
  P_basal = 1.2 + 3.0 m [W] (m the load [kg]);
* power 200 Hz (``BatteryState``, 12 V, ROS sign), force, tip and ``/gait/phase`` 100 Hz;
* standing (``/gait/phase`` ``stand``, period 0) before and after the walk.

``legs`` several: a tripod ``/gait/phase`` (offsets 0 / 0.5) whose leg ``bench`` is the one on
the bench (its force and tip).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer

from hexapod_common.bags import typestore

G = 9.81
M_LEG = 0.2
STEP, HEIGHT = 0.08, 0.03
T0 = 1000.0
TRIPOD = {'L1': 0.0, 'L2': 0.5, 'L3': 0.0, 'R1': 0.5, 'R2': 0.0, 'R3': 0.5}
TYPES = {
    '/battery_state': 'sensor_msgs/msg/BatteryState',
    '/gait/phase': 'hexapod_interfaces/msg/GaitPhase',
    '/bench/ground_force': 'geometry_msgs/msg/WrenchStamped',
    '/bench/leg_tip': 'geometry_msgs/msg/PointStamped',
}


def p_stance(t_st: float, m: float) -> float:
    return 1.5 + 4.0 * m + 0.8 / t_st


def p_swing(t_sw: float, m: float) -> float:
    return 1.0 + 0.5 * m + 1.2 / t_sw


def p_basal(m: float) -> float:
    return 1.2 + 3.0 * m


class _Msgs:
    def __init__(self) -> None:
        self.store = typestore()
        self.T = self.store.types

    def header(self, t: float):
        sec = int(math.floor(t))
        ns = min(int(round((t - sec) * 1e9)), 999_999_999)
        return self.T['std_msgs/msg/Header'](
            stamp=self.T['builtin_interfaces/msg/Time'](sec=sec, nanosec=ns), frame_id='')

    def battery(self, t: float, p: float):
        nan = float('nan')
        return self.T['sensor_msgs/msg/BatteryState'](
            header=self.header(t), voltage=12.0, temperature=nan, current=-p / 12.0,
            charge=nan, capacity=nan, design_capacity=nan, percentage=0.8,
            power_supply_status=2, power_supply_health=0, power_supply_technology=3,
            present=True, cell_voltage=np.zeros(0, np.float32),
            cell_temperature=np.zeros(0, np.float32), location='', serial_number='')

    def wrench(self, t: float, fz: float):
        V3 = self.T['geometry_msgs/msg/Vector3']
        return self.T['geometry_msgs/msg/WrenchStamped'](
            header=self.header(t), wrench=self.T['geometry_msgs/msg/Wrench'](
                force=V3(x=0.0, y=0.0, z=float(fz)), torque=V3(x=0.0, y=0.0, z=0.0)))

    def point(self, t: float, z: float):
        return self.T['geometry_msgs/msg/PointStamped'](
            header=self.header(t), point=self.T['geometry_msgs/msg/Point'](x=0.0, y=0.0,
                                                                          z=float(z)))

    def gait(self, t: float, period: float, beta: float, cyc: float, legs, offsets, stance):
        return self.T['hexapod_interfaces/msg/GaitPhase'](
            header=self.header(t), gait='tripod' if period > 0 else 'stand',
            period=float(period), duty_factor=beta, step_length=STEP if period else 0.0,
            step_height=HEIGHT if period else 0.0, sweep_angle=0.0, leg_offset=0.0,
            cycle_phase=float(cyc), leg_names=list(legs),
            phase_offsets=np.asarray(offsets, float), in_stance=np.asarray(stance, bool),
            supporting_legs=int(sum(stance)))


def _grid(t0: float, t1: float, hz: float) -> np.ndarray:
    return t0 + (np.arange(int(math.floor((t1 - t0) * hz))) + 0.5) / hz


def session_bag(path: Path, *, load: float, freq: float, cycles: int = 6,
                before_s: float = 1.0, tail_s: float = 0.0, t0: float = T0,
                legs: tuple[str, ...] = ('L1',), bench: str = 'L1',
                beta: float = 0.5) -> float:
    """Write one session's bag at ``path`` (standing ``before_s``, ``cycles`` at ``freq`` or
    4 s standing at 0 Hz, standing ``tail_s``); returns its end time [s]."""
    msgs = _Msgs()
    rec: list[tuple[float, str, object]] = []
    offsets = [TRIPOD[x] if len(legs) > 1 else 0.0 for x in legs]
    walk0 = t0 + before_s
    walk1 = walk0 + (cycles / freq if freq > 0 else 4.0)
    end = walk1 + tail_s
    period = 1.0 / freq if freq > 0 else 0.0
    bench_off = offsets[legs.index(bench)]

    def phase(t: float) -> float:
        return ((t - walk0) / period) % 1.0 if period else 0.0

    def walking(t: float) -> bool:
        return freq > 0 and walk0 <= t < walk1

    for t in _grid(t0, end, 200.0):
        if walking(t):
            ph = (phase(t) - bench_off) % 1.0
            p = p_stance(beta * period, load) if ph < beta else \
                p_swing((1 - beta) * period, load)
        else:
            p = p_basal(load)
        rec.append((t, '/battery_state', msgs.battery(t, p)))
    for t in _grid(t0, end, 100.0):
        ph = (phase(t) - bench_off) % 1.0
        down = not walking(t) or ph < beta
        rec.append((t, '/bench/ground_force',
                    msgs.wrench(t, (M_LEG + load) * G if down else 0.0)))
        z = 0.0 if down else HEIGHT * math.sin(math.pi * (ph - beta) / (1 - beta))
        rec.append((t, '/bench/leg_tip', msgs.point(t, z)))
        if walking(t):
            st = [((phase(t) - o) % 1.0) < beta for o in offsets]
            rec.append((t, '/gait/phase', msgs.gait(t, period, beta, phase(t), legs,
                                                    offsets, st)))
        else:
            rec.append((t, '/gait/phase', msgs.gait(t, 0.0, beta, 0.0, legs, offsets,
                                                    [True] * len(legs))))
    rec.sort(key=lambda r: r[0])
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {topic: w.add_connection(topic, typ, typestore=msgs.store)
                 for topic, typ in TYPES.items()}
        for t, topic, msg in rec:
            w.write(conns[topic], int(round((t + 0.0005) * 1e9)),
                    msgs.store.serialize_cdr(msg, TYPES[topic]))
    return end
