"""Robots whose legs are not the Eq. 6 model's 3-DOF leg (an outside review of other leg
shapes): a 12-servo hexapod with 2-DOF legs (``<leg>_coxa``, ``<leg>_femur``) and a hexapod
with 4-DOF legs (``<leg>_tarsus`` beside coxa, femur and tibia). Without joint efforts their
P_out, efficiency and CoT/M were AntBot's 3-DOF leg model (0.307 W for a 2.0 kg tripod at
0.16 m/s, exit 0) with a note that said to give ``--leg``, which takes 3-DOF legs only; now
the model is not evaluated for such legs (P_out from efforts, else unknown, with a
warning; live, `energy_monitor` likewise). Measured numbers from the efforts were right and
stay so (every joint counted)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from rosbags.rosbag2 import Writer

from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
from hexapod_common.testbags import foreign_typestore
from hexapod_energy.cli import main
from hexapod_energy.descriptors import DescriptorAccumulator, model_leg_mismatch

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
OFFSETS = (0.0, 0.5, 0.0, 0.5, 0.0, 0.5)   # tripod: L1 R2 L3 against R1 L2 R3
SCALE = {'coxa': 1.0, 'femur': 1.5, 'tibia': 1.2, 'tarsus': 0.8}
PERIOD_S, BETA, STEP_M = 1.0, 0.5, 0.08     # speed 0.16 m/s
VOLT_V, CURRENT_A = 12.0, -20.0 / 12.0      # P_in 20 W, ROS sign


def _write(path, joints, effort: bool) -> float:
    """A 10 s tripod bag with ``joints`` per leg; returns the true P_out [W]."""
    store = foreign_typestore()
    t = store.types
    hdr = lambda ns: t['std_msgs/msg/Header'](  # noqa: E731
        stamp=t['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id='')
    names = [f'{leg}_{j}' for leg in LEGS for j in joints]
    phase = np.array([2 * math.pi * OFFSETS[LEGS.index(n.split('_')[0])] for n in names])
    scale = np.array([SCALE[n.split('_', 1)[1]] for n in names])
    w = 2 * math.pi / PERIOD_S
    positive = 0.0
    n_js = 1000
    with Writer(path, version=9) as bag:
        cj = bag.add_connection('/joint_states', 'sensor_msgs/msg/JointState', typestore=store)
        cb = bag.add_connection('/battery_state', 'sensor_msgs/msg/BatteryState',
                                typestore=store)
        cg = bag.add_connection('/gait/phase', 'hexapod_interfaces/msg/GaitPhase',
                                typestore=store)
        for k in range(n_js):
            ns = 1_750_000_000 * 10**9 + k * 10_000_000
            th = w * k * 0.01 + phase
            qd = 0.3 * w * np.cos(th)
            tau = scale * (0.1 * np.cos(th) + 0.25 * np.sin(th))
            positive += float(np.maximum(tau * qd, 0.0).sum())
            js = t['sensor_msgs/msg/JointState'](
                header=hdr(ns), name=names, position=0.3 * np.sin(th), velocity=qd,
                effort=tau if effort else np.zeros(0))
            bag.write(cj, ns, store.serialize_cdr(js, cj.msgtype))
            if k % 2:
                continue
            nan = math.nan
            bat = t['sensor_msgs/msg/BatteryState'](
                header=hdr(ns), voltage=VOLT_V, temperature=nan, current=CURRENT_A,
                charge=nan, capacity=nan, design_capacity=nan, percentage=nan,
                power_supply_status=2, power_supply_health=0, power_supply_technology=0,
                present=True, cell_voltage=np.zeros(0, np.float32),
                cell_temperature=np.zeros(0, np.float32), location='', serial_number='')
            bag.write(cb, ns, store.serialize_cdr(bat, cb.msgtype))
            cyc = (k * 0.01 / PERIOD_S) % 1.0
            st = [((cyc - o) % 1.0) < BETA for o in OFFSETS]
            gp = t['hexapod_interfaces/msg/GaitPhase'](
                header=hdr(ns), gait='tripod', period=PERIOD_S, duty_factor=BETA,
                step_length=STEP_M, step_height=0.04, sweep_angle=0.0, leg_offset=0.0,
                cycle_phase=cyc, leg_names=list(LEGS), phase_offsets=np.array(OFFSETS),
                in_stance=np.array(st, dtype=bool), supporting_legs=sum(st))
            bag.write(cg, ns, store.serialize_cdr(gp, cg.msgtype))
    return positive / n_js


def _run(tmp_path, joints, effort):
    bag = tmp_path / 'robot'
    truth = _write(bag, joints, effort)
    out = tmp_path / 'out'
    assert main(['--robot', str(bag), '--robot-mass', '2.0', '--out', str(out),
                 '--no-progress']) == 0
    doc = json.loads((out / 'energy.json').read_text())
    return truth, doc['robot_runs'][0], doc['warnings']


def test_model_leg_mismatch_names_the_legs_and_their_joints() -> None:
    three = [f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia')]
    assert model_leg_mismatch(three) == ''
    assert model_leg_mismatch(three + ['gripper']) == ''
    assert model_leg_mismatch(['j_c1_lf', 'hip_0']) == ''   # not the contract's names
    # three joints of other names: a --leg file may describe them
    assert model_leg_mismatch([f'{leg}_{j}' for leg in LEGS for j in ('a', 'b', 'c')]) == ''
    assert model_leg_mismatch([n for n in three if not n.endswith('tibia')]) == \
        'L1, L2, L3, R1, R2, R3: coxa, femur'
    assert model_leg_mismatch(three + ['L1_tarsus']) == 'L1: coxa, femur, tarsus, tibia'


@pytest.mark.parametrize('joints', [('coxa', 'femur'), ('coxa', 'femur', 'tibia', 'tarsus')])
def test_no_eq6_model_for_legs_it_cannot_describe(tmp_path, joints) -> None:
    _, run, warnings = _run(tmp_path, joints, effort=False)
    assert run['power_out_source'] == 'none'
    assert run['power_out_w'] is None and run['power_out_model_w'] is None
    assert run['efficiency'] is None and run['specific_cost_of_transport'] is None
    assert run['measured_power_in_w'] == pytest.approx(20.0, rel=1e-6)
    assert run['speed'] == pytest.approx(0.16, rel=1e-9)
    assert run['specific_resistance'] == pytest.approx(20.0 / (2.0 * 9.81 * 0.16), rel=1e-6)
    assert any('no Eq. 6 P_out model' in w and 'coxa, femur' in w for w in warnings)


@pytest.mark.parametrize('joints', [('coxa', 'femur'), ('coxa', 'femur', 'tibia', 'tarsus')])
def test_efforts_give_every_joints_power(tmp_path, joints) -> None:
    truth, run, _ = _run(tmp_path, joints, effort=True)
    assert run['power_out_source'] == 'effort'
    assert run['power_out_w'] == pytest.approx(truth, rel=1e-6)
    assert run['power_out_model_w'] is None
    assert run['efficiency'] == pytest.approx(truth / 20.0, rel=1e-6)


def test_three_dof_legs_keep_the_model(tmp_path) -> None:
    _, run, _ = _run(tmp_path, ('coxa', 'femur', 'tibia'), effort=False)
    assert run['power_out_source'] == 'model' and run['power_out_w'] > 0


def _live_windows(joints) -> list:
    """The live accumulator (``energy_monitor``'s core) fed a tripod without efforts, its
    model a stub of 0.5 W."""
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros',
                                power_out_model=lambda gait, mass: 0.5)
    names = tuple(f'{leg}_{j}' for leg in LEGS for j in joints)
    rng = np.random.default_rng(0)
    out = []
    for k in range(500):
        t = 0.01 * k
        out += acc.add_gait_phase(GaitPhaseSample(
            t_s=t, gait='tripod', period_s=PERIOD_S, duty_factor=BETA, step_length_m=STEP_M,
            step_height_m=0.04, sweep_angle_rad=0.0, leg_offset_rad=0.0,
            cycle_phase=(t / PERIOD_S) % 1.0, leg_names=LEGS, phase_offsets=np.array(OFFSETS),
            in_stance=np.ones(6, bool), supporting_legs=3))
        acc.add_joint_state(JointStateSample(t, names, rng.normal(size=len(names)),
                                             rng.normal(size=len(names)), np.empty(0)))
        out += acc.add_battery(BatterySample(t, VOLT_V, CURRENT_A, 25.0))
    assert out
    return out


@pytest.mark.parametrize('joints', [('coxa', 'femur'), ('coxa', 'femur', 'tibia', 'tarsus')])
def test_live_no_eq6_model_for_legs_it_cannot_describe(joints) -> None:
    for d in _live_windows(joints):
        assert math.isnan(d.power_out_w) and d.power_out_source == 'none'
        assert any('no P_out model for these legs' in w for w in d.warnings)
        assert d.power_in_w == pytest.approx(20.0)


def test_live_three_dof_legs_keep_the_model() -> None:
    for d in _live_windows(('coxa', 'femur', 'tibia')):
        assert d.power_out_w == 0.5 and d.power_out_source == 'model'


def test_sweep_and_recommend_say_they_are_not_these_legs(tmp_path) -> None:
    """--sweep/--recommend are the model leg's (reach, P_out): said for 2-DOF robot runs."""
    from test_energy_cli import _write_bench

    _write_bench(tmp_path / 'bench')
    _write(tmp_path / 'robot', ('coxa', 'femur'), effort=True)
    out = tmp_path / 'out'
    assert main(['--bench', str(tmp_path / 'bench'), '--robot', str(tmp_path / 'robot'),
                 '--robot-mass', '2.0', '--recommend', '--speed', '0.16', '--out', str(out),
                 '--no-progress']) == 0
    warnings = json.loads((out / 'energy.json').read_text())['warnings']
    assert any(w.startswith('--sweep/--recommend describe a robot with AntBot') and
               str(tmp_path / 'robot') in w for w in warnings)
