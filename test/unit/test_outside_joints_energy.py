"""Other labs' joint states in the energy analysis: continuous-rotation (RHex-class) hips,
reported unwrapped or wrapped into [-pi, pi), drivers without joint velocities, and a
``/gait/phase`` connection that carries no message.

Reference runs are simulated EduBots (``hexapod_bench_drivers.edubot_sim``; their hip efforts
are output torques [N m]) analysed with ``/gait/phase``; the same runs without it (and with the
velocities emptied) must give the Buehler period and the same P_in and P_out. The AntBot
simulator's efforts are the AX series' PWM load: without velocities the ``auto`` rule must
still refuse them.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer

from hexapod_bench_drivers.edubot_bag import write_run
from hexapod_bench_drivers.edubot_sim import simulate_edubot
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.bags import typestore
from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.cli import main
from hexapod_energy.cycles import (
    JointCycleTracker,
    detrend_linear,
    estimate_period,
    unwrap_near,
)
from hexapod_energy.descriptors import POSITION_POWER_NOTE, DescriptorAccumulator
from hexapod_energy.errors import BagContentError

MASS_KG = 3.3
#: the EduBot needs about one cycle to reach its gait from rest; the joint-derived chain
#: starts at the first sample, the /gait/phase one at the first wrap: compare from here on
SETTLED_S = 1.0
DURATION_S = {'running': 6.0, 'jogging': 6.0, 'pace': 8.0, 'walk': 10.0}


@functools.lru_cache(maxsize=None)
def edubot(gait: str) -> Any:
    return simulate_edubot(gait, duration_s=DURATION_S[gait], seed=1)


def _wrap(q: np.ndarray) -> np.ndarray:
    return (q + np.pi) % (2 * np.pi) - np.pi


def feed(run: Any, cycle_source: str, *, wrap: bool = False, velocity: bool = True,
         power_out_source: str = 'effort') -> tuple[list[Any], DescriptorAccumulator]:
    """The run's streams through the accumulator, as the live node feeds it."""
    acc = DescriptorAccumulator(mass_kg=MASS_KG, cycle_source=cycle_source,
                                power_out_source=power_out_source)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    period = float(run.clock.period_s)
    out: list[Any] = []
    for k, t in enumerate(run.t_s.tolist()):
        q = run.hip_position_rad[k]
        out += acc.add_joint_state(JointStateSample(
            t, names, _wrap(q) if wrap else q,
            run.hip_velocity_rad_s[k] if velocity else np.zeros(0), run.hip_effort_nm[k]))
        if cycle_source == 'gait_phase':
            out += acc.add_gait_phase(GaitPhaseSample(
                t, 'buehler', period, float(run.clock.duty_factor), 0.0, 0.0, 0.0, 0.0,
                (t / period) % 1.0, (), np.zeros(0), np.zeros(0), 0))
        out += acc.add_battery(BatterySample(t, float(run.battery_voltage_v[k]),
                                             float(run.battery_current_a[k]), 25.0))
    return out, acc


def settled_mean(windows: list[Any], t_end_s: float, attr: str) -> float:
    """Time-weighted mean of ``attr`` over the windows inside [SETTLED_S, t_end_s]."""
    sel = [d for d in windows if d.t_end_s - d.window_s >= SETTLED_S and d.t_end_s <= t_end_s]
    assert len(sel) >= 4
    w = np.array([d.window_s for d in sel])
    return float(np.sum(w * np.array([getattr(d, attr) for d in sel])) / np.sum(w))


# -- continuous-rotation joints --------------------------------------------------------------
def test_unwrap_near_takes_the_nearest_representative():
    assert unwrap_near(-3.1, 3.1) == pytest.approx(-3.1 + 2 * math.pi)
    assert unwrap_near(3.1, -3.1) == pytest.approx(3.1 - 2 * math.pi)
    assert unwrap_near(0.2 + 4 * math.pi, 0.1) == pytest.approx(0.2)
    assert unwrap_near(1.0, -2.0) == 1.0      # 3 rad: a jump the joint may make, kept
    assert unwrap_near(0.5, 0.4) == 0.5


def test_ramp_plus_periodic_signal_is_periodic():
    """A hip turning one revolution per cycle with a slow and a fast phase: the ramp alone
    defeats a mean-only normalisation; the least-squares line leaves the periodic part."""
    period_s = 0.45
    t = np.arange(0.0, 14.0, 0.01)
    phase = t / period_s
    hips = np.column_stack([2 * np.pi * (phase + o) + 0.6 * np.sin(2 * np.pi * (phase + o))
                            for o in (0.0, 0.5, 0.0, 0.5, 0.0, 0.5)])
    est = estimate_period(hips)
    assert est.periodic
    np.testing.assert_allclose(est.period_s, period_s, rtol=2e-3)
    # detrending a pure line leaves nothing; a standing robot stays standing
    line = np.outer(t, [1.0, -2.0]) + 3.0
    np.testing.assert_allclose(detrend_linear(line), 0.0, atol=1e-9)
    assert estimate_period(np.full((800, 3), 0.3)).status == 'standing'
    # streaming, wrapped into [-pi, pi) and into [0, 2 pi): the same cycles as unwrapped
    names = [f'h{i}' for i in range(6)]
    bounds = []
    for q in (hips, _wrap(hips), hips % (2 * np.pi)):
        tracker = JointCycleTracker()
        b = [x for k in range(t.size) for x in tracker.add(float(t[k]), names, q[k])]
        np.testing.assert_allclose(tracker.period_s_, period_s, rtol=2e-3)
        bounds.append(np.array(b))
    np.testing.assert_allclose(bounds[1], bounds[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(bounds[2], bounds[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize('gait', ['running', 'jogging', 'pace', 'walk'])
def test_edubot_without_gait_phase_period_and_powers(gait):
    """EduBot Buehler-clock gaits, no /gait/phase, hips unwrapped and wrapped: period within
    1 % of the clock's, P_in within 1 % of the /gait/phase analysis over the settled windows;
    without velocities P_out from position differences within 3 % of the one from them."""
    run = edubot(gait)
    period = float(run.clock.period_s)
    ref, _ = feed(run, 'gait_phase')
    results = []
    for wrap in (False, True):
        win, acc = feed(run, 'joints', wrap=wrap)
        assert win and all(d.cycle_source == 'joints' for d in win)
        np.testing.assert_allclose(acc.tracker_.period_s_, period, rtol=0.01)
        np.testing.assert_allclose([d.window_s for d in win], period, rtol=0.01)
        t_end = min(ref[-1].t_end_s, win[-1].t_end_s)
        np.testing.assert_allclose(settled_mean(win, t_end, 'power_in_w'),
                                   settled_mean(ref, t_end, 'power_in_w'), rtol=0.01)
        np.testing.assert_allclose(settled_mean(win, t_end, 'power_out_w'),
                                   settled_mean(ref, t_end, 'power_out_w'), rtol=0.02)
        results.append(win)
    # wrapped == unwrapped, window for window
    np.testing.assert_allclose([d.power_in_w for d in results[1]],
                               [d.power_in_w for d in results[0]], rtol=1e-12)
    nov, _ = feed(run, 'joints', wrap=True, velocity=False)
    np.testing.assert_allclose([d.t_end_s for d in nov], [d.t_end_s for d in results[0]],
                               rtol=0, atol=1e-9)
    assert all(POSITION_POWER_NOTE in d.warnings for d in nov)
    t_end = nov[-1].t_end_s
    np.testing.assert_allclose(settled_mean(nov, t_end, 'power_out_w'),
                               settled_mean(results[0], t_end, 'power_out_w'), rtol=0.03)


# -- joints without velocities ----------------------------------------------------------------
def test_position_difference_power_is_the_trapezoid_and_streams_over_split_messages():
    """Analytic joint motion and torque: the trapezoid power's positive part per interval
    gives the mean positive joint power; joints split over two messages per sample (one per
    servo bus, stamps a millisecond apart) give the same number as whole messages."""
    t = np.arange(0.0, 8.0, 0.01)
    w = 2 * np.pi / 0.8
    names = [f'j{i}' for i in range(4)]
    ph = np.arange(4) * 0.7
    q = 0.4 * np.sin(w * t[:, None] + ph)
    qd = 0.4 * w * np.cos(w * t[:, None] + ph)
    tau = 0.5 + 1.2 * np.cos(w * t[:, None] + ph + 0.3)
    truth = float(np.mean(np.sum(np.clip(tau * qd, 0, None), axis=1)))

    def mean_pout(split: bool) -> tuple[float, float]:
        acc = DescriptorAccumulator(mass_kg=2.0, cycle_source='joints',
                                    power_out_source='effort')
        out = []
        for k, tk in enumerate(t.tolist()):
            parts = [(0.0, slice(0, 2)), (1e-3, slice(2, 4))] if split else [(0.0, slice(0, 4))]
            for dt, sl in parts:
                out += acc.add_joint_state(JointStateSample(
                    tk + dt, tuple(names[sl]), q[k, sl], np.zeros(0), tau[k, sl]))
            out += acc.add_battery(BatterySample(tk, 12.0, -2.0, 25.0))
        assert len(out) >= 5 and all(POSITION_POWER_NOTE in d.warnings for d in out)
        sel = out[1:]
        return (float(np.mean([d.power_out_w for d in sel])),
                float(np.mean([d.joint_power_net_w for d in sel])))

    whole, net = mean_pout(False)
    split, _ = mean_pout(True)
    np.testing.assert_allclose(whole, truth, rtol=0.01)
    np.testing.assert_allclose(split, whole, rtol=0.01)
    # the net (signed) joint power is the mean of tau qdot: 0.5 * 1.2 * 0.4 w cos(0.3) / 2 * 4
    np.testing.assert_allclose(net, 4 * 0.5 * 1.2 * 0.4 * w * math.cos(0.3), rtol=0.02)


def test_ax_pwm_efforts_without_velocities_still_refused():
    """AntBot with AX-18A servos: the efforts are the PWM duty. Without velocities the
    position-difference power still never goes negative, so ``auto`` refuses it."""
    trace = simulate_robot(10.0, RobotConfig(speed_mps=0.3), seed=2)
    for velocity in (True, False):
        acc = DescriptorAccumulator(mass_kg=2.0, cycle_source='joints')
        out = []
        for k, tk in enumerate(trace.t_s.tolist()):
            out += acc.add_joint_state(JointStateSample(
                tk, tuple(trace.joint_names), trace.position_rad[k],
                trace.velocity_rad_s[k] if velocity else np.zeros(0), trace.effort_nm[k]))
            out += acc.add_battery(BatterySample(tk, float(trace.battery_voltage_v[k]),
                                                 float(trace.battery_current_a[k]), 25.0))
        assert len(out) >= 5
        assert all(math.isnan(d.power_out_w) for d in out)
        assert all(any('never do negative work' in w for w in d.warnings) for d in out)
        assert all((POSITION_POWER_NOTE in d.warnings) != velocity for d in out)


# -- bags --------------------------------------------------------------------------------------
def rewrite(src: Path, dst: Path, *, drop: tuple[str, ...] = (), keep_connection: bool = False,
            fields: tuple[str, ...] = (), wrap: bool = False) -> Path:
    """``src`` with ``drop`` topics removed (their connection kept, empty, with
    ``keep_connection``), the ``/joint_states`` ``fields`` emptied and positions wrapped."""
    store = typestore()
    with AnyReader([src], default_typestore=store) as r, Writer(dst, version=8) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in r.connections if keep_connection or c.topic not in drop}
        for c, t, raw in r.messages():
            if c.topic in drop:
                continue
            if c.topic == '/joint_states' and (fields or wrap):
                msg = r.deserialize(raw, c.msgtype)
                for name in fields:
                    setattr(msg, name, np.zeros(0))
                if wrap and len(msg.position):
                    msg.position = _wrap(np.asarray(msg.position, dtype=float))
                raw = store.serialize_cdr(msg, c.msgtype)
            w.write(conns[c.id], t, raw)
    return dst


@pytest.fixture(scope='module')
def running_bag(tmp_path_factory):
    root = tmp_path_factory.mktemp('edubot')
    return write_run(root / 'ed', edubot('running')), root


def test_velocityless_bag_pout_from_positions(running_bag):
    """The brief's acceptance: the velocity-less twin of a bag gives P_out within a few % of
    the original's (was 0 W), with the fallback named; the same without /gait/phase."""
    bag, root = running_bag
    orig = read_robot_bag(bag, mass_kg=MASS_KG)
    twin = read_robot_bag(rewrite(bag, root / 'nov', fields=('velocity',)), mass_kg=MASS_KG)
    assert orig.extra['cycle_source'] == twin.extra['cycle_source'] == 'gait_phase'
    np.testing.assert_allclose(twin.power_in_w, orig.power_in_w, rtol=1e-12)
    np.testing.assert_allclose(twin.power_out_w, orig.power_out_w, rtol=0.03)
    assert POSITION_POWER_NOTE in twin.extra['notes']
    assert POSITION_POWER_NOTE not in orig.extra['notes']
    nogait = read_robot_bag(rewrite(bag, root / 'ng', drop=('/gait/phase',)), mass_kg=MASS_KG)
    both = read_robot_bag(rewrite(bag, root / 'ngnov', drop=('/gait/phase',),
                                  fields=('velocity',), wrap=True), mass_kg=MASS_KG)
    assert both.extra['cycle_source'] == 'joints' and POSITION_POWER_NOTE in both.extra['notes']
    np.testing.assert_allclose(both.extra['period_s'], edubot('running').clock.period_s,
                               rtol=0.01)
    np.testing.assert_allclose(both.power_in_w, nogait.power_in_w, rtol=1e-12)
    np.testing.assert_allclose(both.power_out_w, nogait.power_out_w, rtol=0.03)


def test_efforts_without_velocities_or_positions_leave_pout_unknown(running_bag):
    bag, root = running_bag
    run = read_robot_bag(rewrite(bag, root / 'effonly', fields=('velocity', 'position')),
                         mass_kg=MASS_KG)
    assert math.isnan(run.power_out_w)
    assert POSITION_POWER_NOTE not in run.extra['notes']


def test_silent_gait_phase_connection_falls_back_to_joints(running_bag):
    """``ros2 bag record -a`` of an advertised but silent /gait/phase: the cycles come from
    the joints (was: refused), with a note; the numbers are those of the bag without it."""
    bag, root = running_bag
    silent = read_robot_bag(rewrite(bag, root / 'silent', drop=('/gait/phase',),
                                    keep_connection=True), mass_kg=MASS_KG)
    nogait = read_robot_bag(rewrite(bag, root / 'ng2', drop=('/gait/phase',)), mass_kg=MASS_KG)
    assert silent.extra['cycle_source'] == 'joints'
    assert '/gait/phase recorded but without messages: cycle boundaries from the joint ' \
        'positions' in silent.extra['notes']
    assert silent.windows == nogait.windows
    np.testing.assert_allclose(silent.power_in_w, nogait.power_in_w, rtol=1e-12)
    np.testing.assert_allclose(silent.power_out_w, nogait.power_out_w, rtol=1e-12)
    # asked for explicitly, the schedule is still required
    with pytest.raises(BagContentError, match='/gait/phase'):
        read_robot_bag(root / 'silent', mass_kg=MASS_KG, cycle_source='gait_phase')


def test_cli_velocityless_antbot_bag(tmp_path):
    """``hexapod-analyze energy --robot BAG`` on a velocity-less AntBot bag (AX PWM efforts):
    ``--power-out effort`` reports the position-difference P_out (was 0 W) with the note;
    ``auto`` still refuses the PWM efforts for the model."""
    trace = simulate_robot(8.0, RobotConfig(speed_mps=0.3), seed=2)
    write_trace(trace, tmp_path / 'rb')
    rewrite(tmp_path / 'rb', tmp_path / 'rb_nov', fields=('velocity',))
    docs = {}
    for name, mode in (('rb', 'effort'), ('rb_nov', 'effort'), ('rb_nov', 'auto')):
        out = tmp_path / f'{name}_{mode}'
        assert main(['--robot', str(tmp_path / name), '--out', str(out), '--power-out', mode,
                     '--no-progress']) == 0
        docs[name, mode] = json.loads((out / 'energy.json').read_text())
    ref = docs['rb', 'effort']['robot_runs'][0]
    nov = docs['rb_nov', 'effort']['robot_runs'][0]
    assert nov['power_out_source'] == 'effort' and POSITION_POWER_NOTE in nov['notes']
    # 21.69 W from velocities, 23.09 W from positions: the measured position carries the
    # servo's compliance under load and 0.0051 rad steps, the velocity the motor's speed
    np.testing.assert_allclose(nov['power_out_w'], ref['power_out_w'], rtol=0.10)
    auto = docs['rb_nov', 'auto']
    assert auto['robot_runs'][0]['power_out_source'] == 'model'
    assert any('never do negative work' in w for w in auto['warnings'])
