"""Independent ground truth for ``slip``: another lab's RHex-like robot, written by an outside
review of this project with its own SLIP integration and rosbags' own ``Writer`` (none of
the project's simulators or writers), kept as it was written so that the tests run on data
whose physics and conventions the analysis was not built around.

Planar SLIP of an RHex-like robot, written to a rosbag2 bag.

Robot ("LabHex"): mass 4.2 kg, half-circle legs R = 0.085 m (chord 0.17 m), hips at
+-0.25 m, hip_z 0, hip_zero 0. Body pitch 0 (COM = hip height). COM motion = an exact planar
SLIP (k, l0, touchdown angle chosen per stance so the stance is symmetric), alternating
tripods (left: L1 R2 L3, right: R1 L2 R3), flights between stances. Hip angles: my own
two-speed clock, slow phase == stance exactly; touchdown/lift-off at the geometric rest-height
crossings (psi_td = -acos(z_td / 2R), psi_lo = acos(z_lo / R - 1)).
"""
from __future__ import annotations

import json
import math

from dataclasses import dataclass, field, asdict
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

G = 9.81


@dataclass
class Cfg:
    mass: float = 4.2
    k: float = 3000.0
    l0: float = 0.16
    R: float = 0.085
    hip_x: tuple = (0.25, 0.0, -0.25)
    vx0: float = 0.9
    apex_z: float = 0.158
    x_start_w: float = -1.3          # world x of the COM at t=0
    duration: float = 3.0
    t0: float = 1234.5               # proprio clock at sim start
    mocap_rate: float = 120.0
    mocap_offset: float = 0.030      # mocap clock minus proprio clock
    mocap_noise: float = 0.0002
    mocap_tilt_deg: float = 2.0
    mocap_yaw_deg: float = 30.0
    mocap_origin_w: tuple = (0.0, 0.0, 0.0)  # world point that is the mocap origin
    frame: str = 'zup'               # 'zup' or 'yup' (OptiTrack: world z -> mocap y)
    body_yup: bool = False           # rigid body defined with y up (OptiTrack default)
    direction: int = 1               # +1 walks along +world x, -1 along -world x
    joint_rate: float = 100.0
    joint_stamp_offset: float = 0.0  # added to /joint_states header stamps (another clock)
    joint_zero_stamps: bool = False
    with_effort: bool = True
    with_commands: bool = True
    with_battery: bool = True
    battery_rate: float = 50.0
    battery_v: float = 15.2
    battery_p: float = 38.0
    battery_p_ripple: float = 6.0
    battery_sign: str = 'ros'        # or positive_discharge
    mocap_nan_frac: float = 0.0
    mocap_gap: tuple | None = None   # (t_start, t_end) in sim time, no frames
    mocap_drop_frac: float = 0.0
    seed: int = 1
    storage: str = 'mcap'
    consistent: bool = True


def simulate(c: Cfg):
    """Return dense truth arrays and the stance list."""
    m, k, l0 = c.mass, c.k, c.l0

    def stance_rhs(_t, y, fx):
        x, vx, z, vz = y
        dx, dz = x - fx, z
        l = math.hypot(dx, dz)
        f = k * (l0 - l) / m
        return [vx, f * dx / l, vz, f * dz / l - G]

    def do_stance(y, alpha, dense=False):
        fx = y[0] + l0 * math.cos(alpha)

        def lo_ev(_t, yy, fx):
            return math.hypot(yy[0] - fx, yy[2]) - l0
        lo_ev.terminal = True
        lo_ev.direction = 1
        sol = solve_ivp(stance_rhs, (0, 1.0), y, args=(fx,), events=lo_ev, rtol=1e-11,
                        atol=1e-12, dense_output=dense, first_step=1e-5, max_step=1e-3)
        return sol, fx

    t = 0.0
    # start at apex
    y = np.array([c.x_start_w, c.vx0, c.apex_z, 0.0])
    segs = []  # (t_start, t_end, kind, params)
    stances = []
    tripod = 'left'
    while t < c.duration + 0.3:
        vx, vz, z = y[1], y[3], y[2]
        # choose the touchdown angle: symmetric stance for the touchdown velocity
        def td_state(alpha):
            ztd = l0 * math.sin(alpha)
            # fall from current z (vz) to ztd
            disc = vz * vz + 2 * G * (z - ztd)
            tf = (vz + math.sqrt(disc)) / G
            return tf, np.array([y[0] + vx * tf, vx, ztd, vz - G * tf])

        def asym(alpha):
            tf, ytd = td_state(alpha)
            sol, fx = do_stance(ytd, alpha)
            return sol.y_events[0][0][3] + ytd[3]
        alpha = brentq(asym, math.radians(60), math.radians(80), xtol=1e-12)
        tf, ytd = td_state(alpha)
        segs.append((t, t + tf, 'flight', y.copy()))
        t += tf
        sol, fx = do_stance(ytd, alpha, dense=True)
        ts = sol.t_events[0][0]
        ylo = sol.y_events[0][0]
        segs.append((t, t + ts, 'stance', (sol, fx)))
        stances.append(dict(tripod=tripod, td=t, lo=t + ts, foot_x_w=fx, k=k, l0=l0,
                            z_td=ytd[2], z_lo=ylo[2], alpha_deg=math.degrees(alpha)))
        t += ts
        y = ylo.copy()
        tripod = 'right' if tripod == 'left' else 'left'
    # segment with remaining flight
    segs.append((t, t + 1.0, 'flight', y.copy()))

    def state_at(tt):
        out = np.empty((len(tt), 4))
        for i, ti in enumerate(tt):
            for (a, b, kind, p) in segs:
                if a <= ti < b or (kind == 'flight' and ti >= a and (a, b) == segs[-1][:2]):
                    if kind == 'flight':
                        dt = ti - a
                        out[i] = [p[0] + p[1] * dt, p[1], p[2] + p[3] * dt - 0.5 * G * dt * dt,
                                  p[3] - G * dt]
                    else:
                        sol, fx = p
                        out[i] = sol.sol(ti - a)
                    break
            else:
                raise RuntimeError(ti)
        return out
    return stances, state_at


def rest_height(psi, R):
    psi = (np.asarray(psi) + math.pi) % (2 * math.pi) - math.pi
    return np.where(psi < 0, 2 * R * np.cos(psi), R * (1 + np.cos(psi)))


def hip_clock(c: Cfg, stances, tt, state_at=None):
    """psi(t), psi'(t) per tripod, slow phase = each stance exactly. With ``state_at``, the
    stance psi(t) is physically consistent with three radial leg springs of stiffness k_w each
    whose deflection is the geometric penetration rest(psi) - z: 3 k_w (rest - z) = SLIP
    vertical force (rest peaks at 2R at mid-stance)."""
    R = c.R
    out = {}
    if state_at is not None:
        res = hip_clock(c, stances, tt)
        for tp in ('left', 'right'):
            psi, vel = res[tp]
            base = 0.0
            psi = psi.copy()
            for s in [s for s in stances if s['tripod'] == tp]:
                k_ = (tt >= s['td']) & (tt <= s['lo'])
                ti = tt[k_]
                st = state_at(ti)
                z = st[:, 2]
                l = np.hypot(st[:, 0] - s['foot_x_w'], z)
                fz = (c.l0 - l) * z / l
                j = int(np.argmax(fz))
                cs = (2 * R - z[j]) / fz[j]
                s['kw_per_leg'] = c.k / (3 * cs)
                rest = np.minimum(z + cs * fz, 2 * R)
                p = np.where(np.arange(ti.size) <= j, -np.arccos(np.clip(rest / (2 * R), -1, 1)),
                             np.arccos(np.clip(rest / R - 1, -1, 1)))
                # add the tripod's turn count (psi unwrapped)
                turns = np.round((psi[k_][0] - p[0]) / (2 * np.pi)) * 2 * np.pi
                psi[k_] = p + turns
            vel = np.gradient(psi, tt)
            out[tp] = (psi, vel)
        return out
    for tp in ('left', 'right'):
        st = [s for s in stances if s['tripod'] == tp]
        knots_t, knots_p = [], []
        base = 0.0
        for s in st:
            ptd = -math.acos(min(1, s['z_td'] / (2 * R)))
            plo = math.acos(s['z_lo'] / R - 1)
            knots_t += [s['td'], s['lo']]
            knots_p += [base + ptd, base + plo]
            base += 2 * math.pi
        knots_t, knots_p = np.array(knots_t), np.array(knots_p)
        # extrapolate before the first touchdown at the first fast speed
        fast = (knots_p[2] - knots_p[1]) / (knots_t[2] - knots_t[1])
        psi = np.interp(tt, knots_t, knots_p)
        pre = tt < knots_t[0]
        psi[pre] = knots_p[0] - fast * (knots_t[0] - tt[pre])
        post = tt > knots_t[-1]
        psi[post] = knots_p[-1] + fast * (tt[post] - knots_t[-1])
        slopes = np.diff(knots_p) / np.diff(knots_t)
        idx = np.clip(np.searchsorted(knots_t, tt, side='right') - 1, -1, len(slopes))
        vel = np.where(idx < 0, fast, np.where(idx >= len(slopes), fast,
                                               slopes[np.clip(idx, 0, len(slopes) - 1)]))
        out[tp] = (psi, vel)
    return out


def geometric_check(c, stances, state_at, clock, dense_t):
    """My own contact check: rest(psi) > z exactly during stances (for the truth)."""
    tt = np.arange(0.02, c.duration, 1e-4)
    z = state_at(tt)[:, 2]
    bad = 0
    for tp in ('left', 'right'):
        psi, _ = clock[tp]
        psi = np.interp(tt, dense_t, psi)
        contact = rest_height(psi, c.R) > z
        truth = np.zeros_like(contact)
        for s in stances:
            if s['tripod'] == tp:
                truth |= (tt > s['td'] + 2e-4) & (tt < s['lo'] - 2e-4)
        edge = np.zeros_like(contact)
        for s in stances:
            edge |= (np.abs(tt - s['td']) <= 2e-4) | (np.abs(tt - s['lo']) <= 2e-4)
        bad += int(np.sum((contact != truth) & ~edge))
    return bad


def mocap_rotation(c: Cfg) -> np.ndarray:
    """R_mw: world vectors -> mocap vectors."""
    r = Rotation.from_euler('zy', [c.mocap_yaw_deg, c.mocap_tilt_deg], degrees=True)
    rm = r.as_matrix()
    if c.frame == 'yup':
        # OptiTrack: mocap x = world x, mocap y = world z (up), mocap z = -world y
        yup = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], dtype=float)
        rm = yup @ rm
    return rm


def build(c: Cfg, out: Path, truth_path: Path | None = None, extra_missing=()):
    """Write the bag of ``c`` to ``out``; returns (truth dict, state_at(t) -> (n, 4)
    [x, x', z, z'] world COM state), the truth with the stances' touchdown ``td`` and lift-off
    ``lo`` in seconds from the start (proprio clock ``c.t0 + t``)."""
    from rosbags.rosbag2 import Writer, StoragePlugin
    from rosbags.typesys import Stores, get_typestore
    rng = np.random.default_rng(c.seed)
    ts = get_typestore(Stores.ROS2_JAZZY)
    stances, state_at = simulate(c)
    stances = [s for s in stances if s['lo'] < c.duration]
    dense_t = np.arange(0, c.duration + 0.3, 1e-4)
    clock = hip_clock(c, stances, dense_t, state_at if c.consistent else None)
    clock_cmd = hip_clock(c, stances, dense_t)   # the two-speed target (slow phase = stance)
    bad = geometric_check(c, stances, state_at, clock, dense_t)
    Msg = ts.types
    Header = Msg['std_msgs/msg/Header']
    Time = Msg['builtin_interfaces/msg/Time']
    def stamp(t):
        if t <= 0:
            return Time(sec=0, nanosec=0)
        ns = int(round(t * 1e9))
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    rm = mocap_rotation(c)
    # world positions: direction -1 means the world path is mirrored (robot faces -x)
    names = ['L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip']
    tri = {'L1_hip': 'left', 'R2_hip': 'left', 'L3_hip': 'left',
           'R1_hip': 'right', 'L2_hip': 'right', 'R3_hip': 'right'}
    msgs = []  # (recv_ns, topic, msg)
    # --- mocap
    tm = np.arange(0.0, c.duration, 1.0 / c.mocap_rate) + rng.uniform(0, 1 / c.mocap_rate)
    tm = tm[tm < c.duration]
    st = state_at(tm)
    pw = np.column_stack([c.direction * st[:, 0], np.zeros(len(tm)), st[:, 2]])
    body_w = Rotation.from_euler('z', 0 if c.direction > 0 else 180, degrees=True)
    pm = (pw - np.asarray(c.mocap_origin_w)) @ rm.T
    pm += rng.normal(0, c.mocap_noise, pm.shape)
    qb = Rotation.from_matrix(rm) * body_w
    if c.body_yup:
        # rigid body created with its y axis up: body frame y = robot up, z = -robot lateral
        qb = qb * Rotation.from_matrix(np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float).T)
    PoseStamped = Msg['geometry_msgs/msg/PoseStamped']
    Pose = Msg['geometry_msgs/msg/Pose']
    Point = Msg['geometry_msgs/msg/Point']
    Quat = Msg['geometry_msgs/msg/Quaternion']
    for i, t in enumerate(tm):
        if c.mocap_gap and c.mocap_gap[0] <= t < c.mocap_gap[1]:
            continue
        if c.mocap_drop_frac and rng.random() < c.mocap_drop_frac:
            continue
        noise = Rotation.from_rotvec(rng.normal(0, 0.0005, 3))
        q = (qb * noise).as_quat()
        p = pm[i]
        if c.mocap_nan_frac and rng.random() < c.mocap_nan_frac:
            p = [math.nan] * 3
            q = [math.nan] * 4
        msg = PoseStamped(header=Header(stamp=stamp(c.t0 + t + c.mocap_offset), frame_id='mocap'),
                          pose=Pose(position=Point(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                                    orientation=Quat(x=float(q[0]), y=float(q[1]), z=float(q[2]),
                                                     w=float(q[3]))))
        msgs.append((int((c.t0 + t + 0.004) * 1e9), '/mocap/body', msg))
    # --- joints
    tj = np.arange(0.0, c.duration, 1.0 / c.joint_rate)
    JointState = Msg['sensor_msgs/msg/JointState']
    psi = {tp: np.interp(tj, dense_t, clock[tp][0]) for tp in ('left', 'right')}
    vel = {tp: np.interp(tj, dense_t, clock[tp][1]) for tp in ('left', 'right')}
    cpsi = {tp: np.interp(tj, dense_t, clock_cmd[tp][0]) for tp in ('left', 'right')}
    cvel = {tp: np.interp(tj, dense_t, clock_cmd[tp][1]) for tp in ('left', 'right')}
    # stance mask per tripod for efforts
    instance = {tp: np.zeros(len(tj), bool) for tp in ('left', 'right')}
    for s in stances:
        instance[s['tripod']] |= (tj >= s['td']) & (tj <= s['lo'])
    for i, t in enumerate(tj):
        pos = [psi[tri[n]][i] + rng.normal(0, 0.001) for n in names]
        v = [vel[tri[n]][i] + rng.normal(0, 0.05) for n in names]
        eff = ([(1.2 if instance[tri[n]][i] else 0.15) + rng.normal(0, 0.03) for n in names]
               if c.with_effort else [])
        js_t = 0.0 if c.joint_zero_stamps else c.t0 + t + c.joint_stamp_offset
        msg = JointState(header=Header(stamp=stamp(js_t), frame_id=''), name=names,
                         position=np.array(pos), velocity=np.array(v), effort=np.array(eff))
        msgs.append((int((c.t0 + t + 0.002) * 1e9), '/joint_states', msg))
        if c.with_commands:
            cm = JointState(header=Header(stamp=stamp(c.t0 + t), frame_id=''), name=names,
                            position=np.array([cpsi[tri[n]][i] for n in names]),
                            velocity=np.array([cvel[tri[n]][i] for n in names]),
                            effort=np.array([]))
            msgs.append((int((c.t0 + t + 0.001) * 1e9), '/joint_commands', cm))
    # --- battery: P(t) = P + ripple sin(2 pi t / 0.7)
    btruth = None
    if c.with_battery:
        BatteryState = Msg['sensor_msgs/msg/BatteryState']
        tb = np.arange(0.0, c.duration, 1.0 / c.battery_rate)
        P = c.battery_p + c.battery_p_ripple * np.sin(2 * math.pi * tb / 0.7)
        V = c.battery_v + rng.normal(0, 0.01, len(tb))
        I = P / V
        if c.battery_sign == 'ros':
            I = -I
        btruth = dict(t=tb.tolist(), P=(P).tolist(), V=V.tolist(), I=I.tolist())
        for i, t in enumerate(tb):
            msg = BatteryState(header=Header(stamp=stamp(c.t0 + t), frame_id='bat'),
                               voltage=float(V[i]), temperature=25.0, current=float(I[i]),
                               charge=math.nan, capacity=math.nan, design_capacity=math.nan,
                               percentage=0.8, power_supply_status=2, power_supply_health=1,
                               power_supply_technology=3, present=True,
                               cell_voltage=np.array([], dtype=np.float32),
                               cell_temperature=np.array([], dtype=np.float32),
                               location='', serial_number='')
            msgs.append((int((c.t0 + t + 0.003) * 1e9), '/battery_state', msg))
    msgs.sort(key=lambda m: m[0])
    types = {'/mocap/body': 'geometry_msgs/msg/PoseStamped',
             '/joint_states': 'sensor_msgs/msg/JointState',
             '/joint_commands': 'sensor_msgs/msg/JointState',
             '/battery_state': 'sensor_msgs/msg/BatteryState'}
    if out.exists():
        import shutil
        shutil.rmtree(out)
    plugin = StoragePlugin.MCAP if c.storage == 'mcap' else StoragePlugin.SQLITE3
    with Writer(out, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic in sorted({m[1] for m in msgs}):
            if topic in extra_missing:
                continue
            conns[topic] = w.add_connection(topic, types[topic], typestore=ts)
        for recv, topic, msg in msgs:
            if topic in conns:
                w.write(conns[topic], recv, ts.serialize_cdr(msg, types[topic]))
    # truth
    tin = tm  # world path for speed
    truth = dict(cfg=asdict(c), stances=stances, geometric_mismatch_samples=bad)
    # expected speed over the whole tracked run (first to last mocap sample)
    x = state_at(np.array([tm[0], tm[-1]]))[:, 0]
    truth['speed_whole'] = float((x[1] - x[0]) / (tm[-1] - tm[0]))
    if btruth:
        truth['battery_mean_P'] = float(np.mean(btruth['P']))
        truth['battery_mean_VI'] = float(np.mean(np.array(btruth['V']) * np.abs(btruth['I'])))
    truth['x_first_mocap_w'] = float(state_at(tm[:1])[0, 0])
    truth['mocap_t'] = tm.tolist()
    truth['mocap_pm'] = pm.tolist()
    if btruth:
        truth['battery'] = btruth
    if truth_path:
        truth_path.write_text(json.dumps(truth, indent=1, default=float))
    return truth, state_at
