"""Write a simulator's :class:`~.sim_core.SimTrace` into a rosbag2 bag as the real drivers' topics.

Topics (DESIGN section 4): ``/joint_states``, ``/joint_commands``, ``/gait/phase`` (every sample),
``/servo_status`` (every ``status_every`` samples), ``/battery_state`` (every sample, ROS sign:
current negative while discharging), and for the bench ``/bench/ground_force``,
``/bench/leg_tip`` and ``/bench/session`` (one message per state change). The effect set goes
into the bag's metadata only (custom data ``hexapod_sim.effects``), with the run's configuration
under ``hexapod_sim.config``.

Stamps and bag times (the same convention in :mod:`edubot_bag`): ``header.stamp`` is the time
the device (or its driver) stamps the sample with, the bag time the recorder's clock when it
receives it; a sample of the true instant ``t`` is, without effects, stamped and received at
``t``.

* A **clock offset** moves the stamp only: the device's clock is off, the sample still arrives
  at ``t`` (``time_offset``: ``/battery_state`` stamped ``t + value``, received at ``t``;
  EduBot's ``time_offset``: ``/mocap/body`` likewise). Its stamp may be later than its bag time.
* A **transport delay** moves both: the driver reads the sample ``value`` seconds after the
  instant it describes, stamps it then and the recorder receives it then, so the bag time is
  never earlier than the stamp (``sensor_latency``: ``/joint_states`` and ``/servo_status``
  stamped and received at ``t + value``, describing ``t``).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from os import PathLike
from typing import Any

import numpy as np

from hexapod_common.bags import BagWriter

from . import sim_cdr as cdr
from .effects import METADATA_KEY
from .sim_core import SimTrace

__all__ = ['CONFIG_KEY', 'DEFAULT_START_NS', 'write_trace']

#: Custom-data key of the run's configuration (JSON) in the bag's metadata.
CONFIG_KEY = 'hexapod_sim.config'
#: Bag time of the simulation's t = 0 (fixed, so that the same seed gives the same bag).
DEFAULT_START_NS = 1_700_000_000_000_000_000


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


def _session_bytes(r: Any, rec_ns: int) -> bytes:
    b = cdr.CdrBuffer()
    b.header(rec_ns, 'bench')
    b.string(r.session_id)
    b.string(r.state)
    b.pack('ddddd', 8, float(r.load_mass_kg), float(r.frequency_hz), float(r.duty_factor),
           float(r.step_length_m), float(r.step_height_m))
    return b.bytes()


def _write(w: BagWriter, tr: SimTrace, start_ns: int, status_every: int,
           progress: Callable[[int], None] | None) -> None:
    names = list(tr.joint_names)
    legs = list(tr.leg_names)
    offsets = np.asarray(tr.phase_offsets, dtype=np.float64)
    sessions = sorted(tr.sessions, key=lambda r: r.t_s)
    si = 0
    js_t, bat_t = 'sensor_msgs/msg/JointState', 'sensor_msgs/msg/BatteryState'
    session_t = 'hexapod_interfaces/msg/BenchSession'
    bench = tr.ground_force_n is not None and tr.tip_m is not None
    zero3 = (0.0, 0.0, 0.0)
    for k in range(tr.sample_count):
        t = float(tr.t_s[k])
        t_ns = _ns(start_ns, t)
        while si < len(sessions) and sessions[si].t_s <= t:
            rec_ns = _ns(start_ns, sessions[si].t_s)
            w.write('/bench/session', session_t, _session_bytes(sessions[si], rec_ns), rec_ns)
            si += 1
        # sensor_latency, a transport delay: stamped when the driver reads the bus and
        # received then too (never before the stamp, nor before the instant described)
        servo_ns = _ns(start_ns, t + tr.servo_stamp_offset_s)
        servo_rec_ns = max(servo_ns, t_ns)
        w.write('/joint_states', js_t, cdr.joint_state(
            servo_ns, names, tr.position_rad[k], tr.velocity_rad_s[k], tr.effort_nm[k]),
            servo_rec_ns)
        w.write('/joint_commands', js_t, cdr.joint_state(
            t_ns, names, tr.command_position_rad[k], tr.command_velocity_rad_s[k], ()), t_ns)
        w.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase', cdr.gait_phase(
            t_ns, str(tr.gait_name[k]), float(tr.period_s[k]), float(tr.duty_factor[k]),
            float(tr.step_length_m[k]), float(tr.step_height_m[k]), float(tr.cycle_phase[k]),
            legs, offsets, tr.in_stance[k], int(tr.supporting_legs[k])), t_ns)
        if k % status_every == 0:
            w.write('/servo_status', 'hexapod_interfaces/msg/ServoStatus', cdr.servo_status(
                servo_ns, names, tr.temperature_c[k], tr.servo_voltage_v[k],
                tr.load_fraction[k], tr.servo_error[k]), servo_rec_ns)
        # time_offset, a clock offset: the stamp moves, the sample arrives at t
        bat_ns = _ns(start_ns, t + tr.battery_stamp_offset_s)
        w.write('/battery_state', bat_t, cdr.battery_state(
            bat_ns, float(tr.battery_voltage_v[k]), float(tr.battery_current_a[k]),
            status=2 if tr.powered[k] else 3, frame_id='supply'), t_ns)
        if bench:
            assert tr.ground_force_n is not None and tr.tip_m is not None
            w.write('/bench/ground_force', 'geometry_msgs/msg/WrenchStamped',
                    cdr.wrench_stamped(t_ns, (0.0, 0.0, float(tr.ground_force_n[k])), zero3,
                                       'bench'), t_ns)
            w.write('/bench/leg_tip', 'geometry_msgs/msg/PointStamped',
                    cdr.point_stamped(t_ns, tuple(float(x) for x in tr.tip_m[k]), 'bench'),
                    t_ns)
        if progress is not None and k % 1000 == 999:
            progress(1000)
    while si < len(sessions):
        rec_ns = _ns(start_ns, sessions[si].t_s)
        w.write('/bench/session', session_t, _session_bytes(sessions[si], rec_ns), rec_ns)
        si += 1
