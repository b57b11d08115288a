"""Generated bags for tests and benchmarks (no committed data)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hexapod_common.bags import BagWriter, new_msg, stamp

__all__ = ['write_mixed_bag']

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
JOINTS = [f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia')]


def write_mixed_bag(path: str | Path, n_messages: int, *, storage: str = 'mcap',
                    rate_hz: float = 100.0, t0_ns: int = 1_700_000_000_000_000_000
                    ) -> dict[str, int]:
    """A bag of ``n_messages`` JointState (18 joints), BatteryState and GaitPhase, in turn.

    Returns the count per topic.
    """
    topics = ('/joint_states', '/battery_state', '/gait/phase')
    counts = dict.fromkeys(topics, 0)
    dt_ns = int(1e9 / rate_hz)
    with BagWriter(path, storage=storage) as writer:
        for k in range(n_messages):
            tick, which = divmod(k, 3)
            t_ns = t0_ns + tick * dt_ns + which * 1000
            t = tick / rate_hz
            header = stamp(t_ns)
            if which == 0:
                q = np.sin(t + np.arange(18))
                msg = new_msg('sensor_msgs/msg/JointState', header=header, name=JOINTS,
                              position=q, velocity=np.cos(t + np.arange(18)), effort=0.1 * q)
                writer.write(topics[0], 'sensor_msgs/msg/JointState', msg, t_ns)
            elif which == 1:
                msg = new_msg('sensor_msgs/msg/BatteryState', header=header, voltage=11.9,
                              current=-2.0 - 0.5 * math.sin(t), present=True)
                writer.write(topics[1], 'sensor_msgs/msg/BatteryState', msg, t_ns)
            else:
                phase = t % 1.0
                in_stance = [((phase - o) % 1.0) < 0.5 for o in (0, .5, 0, .5, 0, .5)]
                msg = new_msg('hexapod_interfaces/msg/GaitPhase', header=header, gait='tripod',
                              period=1.0, duty_factor=0.5, step_length=0.1, step_height=0.04,
                              cycle_phase=phase, leg_names=list(LEGS),
                              phase_offsets=[0, .5, 0, .5, 0, .5], in_stance=in_stance,
                              supporting_legs=sum(in_stance))
                writer.write(topics[2], 'hexapod_interfaces/msg/GaitPhase', msg, t_ns)
            counts[topics[which]] += 1
    return counts
