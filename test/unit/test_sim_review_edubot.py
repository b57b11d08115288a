"""Simulator review, EduBot part: hip_torque, leg_damping's range, stamps against bag times,
``--seed`` documented as physics.

Each test fails on the code the review found: ``hip_torque`` lowered the stance hip effort and
the battery power; ``sensor_latency`` moved the ``/joint_states`` stamp but not its bag time (a
message received before its stamp) while ``/servo_status`` moved both; EduBot's ``/mocap/body``
was received at its offset stamp; ``--seed`` was described as a noise seed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexapod_bench_drivers.edubot_bag import add_cli as add_edubot_cli
from hexapod_bench_drivers.edubot_bag import write_run
from hexapod_bench_drivers.edubot_sim import (
    EdubotRun,
    run_summary,
    simulate_edubot,
    simulate_edubot_batch,
)
from hexapod_bench_drivers.effects import parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import DEFAULT_START_NS, write_trace
from hexapod_common.bags import iter_messages, open_reader, typestore

QUIET = {'mocap_noise': 0.0, 'mocap_misalignment': 0.0}


def stance_effort(run: EdubotRun) -> float:
    """Mean hip effort over the samples of legs in contact after the settle [N m]."""
    contact = run.fine_contact[::10][:len(run.t_s)]
    sel = (run.t_s >= run.params.settle_s)[:, None] & contact
    return float(run.hip_effort_nm[sel].mean())


def max_lag(run: EdubotRun) -> float:
    """Largest clock target minus hip angle after the settle [rad]."""
    late = run.t_s > run.params.settle_s
    return float(np.abs(run.target_position_rad - run.hip_position_rad)[late].max())


# --------------------------------------------------------------------------------------------
# hip_torque
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('gait', ['walk', 'jogging', 'pace'])
def test_hip_torque_adds_value_over_three_per_stance_leg_paid_by_the_battery(gait: str) -> None:
    value = 0.3
    base = simulate_edubot(gait, duration_s=7.5, seed=0, effects=QUIET)
    run = simulate_edubot(gait, duration_s=7.5, seed=0, effects={**QUIET, 'hip_torque': value})
    d_tau = stance_effort(run) - stance_effort(base)
    # was -0.046 N m (jogging, seed 3) and -0.010 (walk): the loop cancelled the feed-forward
    assert d_tau == pytest.approx(value / 3, rel=0.2)
    sb, sr = run_summary(base), run_summary(run)
    # the motor pays: its work plus copper and gear losses (was -1.7 W jogging, -0.5 W walk)
    assert sr['power_w'] > sb['power_w'] + 1.0
    # an extra stance load met by its feed-forward: the body's motion about unchanged
    assert sr['speed_m_s'] == pytest.approx(sb['speed_m_s'], abs=0.03)
    assert max_lag(run) < 1.0


def test_hip_torque_scales_with_its_value_in_the_walk() -> None:
    runs = simulate_edubot_batch('walk', duration_s=6.0, seeds=(3,), effects=QUIET)
    taus, powers = [stance_effort(runs[0])], [run_summary(runs[0])['power_w']]
    for value in (0.15, 0.3, 0.6):
        run = simulate_edubot('walk', duration_s=6.0, seed=3,
                              effects={**QUIET, 'hip_torque': value})
        taus.append(stance_effort(run))
        powers.append(run_summary(run)['power_w'])
        assert taus[-1] - taus[0] == pytest.approx(value / 3, rel=0.15)
    assert np.all(np.diff(taus) > 0) and np.all(np.diff(powers) > 0)


def test_hip_torque_off_leaves_the_run_bit_identical() -> None:
    a = simulate_edubot('jogging', duration_s=2.5, seed=3)
    b = simulate_edubot('jogging', duration_s=2.5, seed=3, effects={'hip_torque': 0.0})
    assert np.array_equal(a.hip_effort_nm, b.hip_effort_nm)
    assert np.array_equal(a.battery_current_a, b.battery_current_a)


# --------------------------------------------------------------------------------------------
# leg_damping: the documented plain-loss range, and the stalled mode beyond it
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('gait,values', [('running', (0.0, 2.0, 4.0, 6.0)),
                                         ('jogging', (0.0, 5.0, 10.0, 15.0)),
                                         ('walk', (0.0, 15.0, 45.0))])
def test_leg_damping_is_a_plain_loss_over_its_documented_range(gait: str, values: tuple) -> None:
    seeds = (0, 3)
    power, speed = [], []
    for value in values:
        runs = simulate_edubot_batch(gait, duration_s=6.0, seeds=seeds,
                                     effects={**QUIET, 'leg_damping': value})
        power.append([run_summary(r)['power_w'] for r in runs])
        speed.append([run_summary(r)['speed_m_s'] for r in runs])
        assert max(max_lag(r) for r in runs) < 1.0         # no leg falls behind its clock
    p, v = np.array(power), np.array(speed)
    assert np.all(np.diff(p, axis=0) > 0.0)                 # monotonic loss, every seed
    assert np.all(np.diff(v, axis=0) <= 1e-3)
    assert np.all(v[-1] > v[0] - 0.1)


def test_leg_damping_beyond_the_range_tips_the_running_into_the_stalled_mode() -> None:
    """Documented behaviour (module docstring, README): not a plain loss any more."""
    base = simulate_edubot('running', duration_s=7.5, seed=3, effects=QUIET)
    run = simulate_edubot('running', duration_s=7.5, seed=3,
                          effects={**QUIET, 'leg_damping': 30.0})
    assert max_lag(run) > math.pi                           # a leg loses about a turn
    assert run_summary(run)['power_w'] > run_summary(base)['power_w'] + 15.0


# --------------------------------------------------------------------------------------------
# stamps against bag receive times
# --------------------------------------------------------------------------------------------
def _stamps(path) -> dict[str, list[tuple[int, int]]]:
    """``{topic: [(bag time, header stamp) ns, ...]}`` in bag order."""
    store = typestore()
    out: dict[str, list[tuple[int, int]]] = {}
    with open_reader(path) as reader:
        for m in iter_messages(reader):
            msg = store.deserialize_cdr(m.data, m.msgtype)
            st = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            out.setdefault(m.topic, []).append((m.stamp_ns, st))
    return out


def test_sensor_latency_moves_stamp_and_receive_time_of_both_servo_topics(tmp_path) -> None:
    latency, offset = 0.02, 0.05
    effects = parse_effects([f'sensor_latency={latency}', f'time_offset={offset}'])
    tr = simulate_robot(0.5, RobotConfig(speed_mps=0.3), effects=effects, seed=5)
    write_trace(tr, tmp_path / 'bag', seed=5)
    got = _stamps(tmp_path / 'bag')
    true_ns = DEFAULT_START_NS + np.round(np.asarray(tr.t_s) * 1e9).astype(np.int64)
    for topic in ('/joint_states', '/servo_status'):
        rec, st = np.array(got[topic]).T
        # stamped when the driver read the bus, received then: never before the stamp
        assert np.all(rec >= st), topic
        assert np.all(rec == st), topic
        n = len(st)
        idx = np.arange(n) * (10 if topic == '/servo_status' else 1)
        np.testing.assert_allclose(st - true_ns[idx], latency * 1e9, atol=2)
    rec, st = np.array(got['/battery_state']).T
    np.testing.assert_array_equal(rec, true_ns)             # a clock offset: stamp only
    np.testing.assert_allclose(st - rec, offset * 1e9, atol=2)
    for topic in ('/joint_commands', '/gait/phase'):
        rec, st = np.array(got[topic]).T
        np.testing.assert_array_equal(rec, st)


def test_edubot_mocap_offset_moves_the_stamp_only(tmp_path) -> None:
    offset = 0.025
    run = simulate_edubot('pace', duration_s=2.5, seed=2, effects={'time_offset': offset})
    got = _stamps(write_run(tmp_path / 'bag', run))
    rec, st = np.array(got['/mocap/body']).T
    np.testing.assert_array_equal(st, np.round(run.mocap_t_s * 1e9).astype(np.int64))
    # received at the true sample time, stamped in the mocap clock (was received at the stamp)
    np.testing.assert_allclose(st - rec, offset * 1e9, atol=2)
    for topic in ('/joint_states', '/joint_commands', '/gait/phase', '/battery_state'):
        rec, st = np.array(got[topic]).T
        np.testing.assert_array_equal(rec, st)
    # the bag is in receive-time order across topics
    with open_reader(tmp_path / 'bag') as reader:
        times = [m.stamp_ns for m in iter_messages(reader)]
    assert np.all(np.diff(times) >= 0)


# --------------------------------------------------------------------------------------------
# --seed documented as physics
# --------------------------------------------------------------------------------------------
def test_edubot_seed_help_says_it_changes_the_physics() -> None:
    import argparse

    ap = argparse.ArgumentParser(prog='hexapod-sim')
    add_edubot_cli(ap.add_subparsers(dest='command'))
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    text = ' '.join(sub.choices['edubot'].format_help().split())
    assert 'changes the physics' in text
    assert 'open-circuit voltage' in text and 'initial speed' in text
    # and it does: two seeds, two battery voltages before the first step's load
    a, b = simulate_edubot_batch('walk', duration_s=0.5, seeds=(0, 1), effects=QUIET)
    assert a.battery_voltage_v[0] != b.battery_voltage_v[0]
