"""More of another lab's driver quirks through the offline energy analysis, found by an outside
review with its own bags (``/tmp``-written with rosbags, expected figures by hand): each of these
gave a wrong number with exit 0, or lost data without a note, before.

- a battery sensor's idle offset before the servos draw current decided ``auto``'s current sign
  for the whole run (P_in -36.8 W for +37.7 W);
- millivolts with a current under 1 A in milliamps: the current was left in mA (P_in 1000x);
- NaN efforts on joints without an effort interface, or a sporadic NaN velocity, lost the
  measured P_out of the whole run with no note;
- a wrong current sign gave a negative P_in with no note (and blamed the efforts);
- odometry publishing only its twist (pose left at 0) gave a speed of 0 m/s as a measurement;
- an advertised but silent ``/battery_state`` was refused blaming the joint cycles;
- a window across a recording gap interpolated P_in over the missing seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.battery import milli_factors
from hexapod_common.conversions import BatterySample
from hexapod_common.testbags import ODOM_SPEED_MPS, P0_W
from hexapod_common.testbags import write_foreign_robot_bag as write_bag
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.descriptors import DescriptorAccumulator, implausible_effort_power
from hexapod_energy.errors import BagContentError


def _pout(truth: dict) -> float:
    return float(np.mean(truth['pout'][:, 1]))


def test_idle_offset_at_start_does_not_decide_the_current_sign(tmp_path):
    write_bag(tmp_path / 'bag', idle_offset_samples=3)
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0, current_sign='auto')
    assert run.current_sign == -1.0
    np.testing.assert_allclose(run.power_in_w, P0_W, rtol=0.02)
    # the contract's sign needs no note; positive-on-discharge is said
    assert not any('auto-detected' in n for n in run.extra['notes'])
    write_bag(tmp_path / 'pos', sign=+1.0, idle_offset_samples=3)
    run = read_robot_bag(tmp_path / 'pos', mass_kg=2.0, current_sign='auto')
    assert run.current_sign == 1.0
    assert any('positive while discharging' in n for n in run.extra['notes'])


def test_live_accumulator_ignores_an_idle_offset_for_its_early_decision():
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='auto')
    for k in range(3):  # +20 mA at 11.5 V: 0.23 W each, under the 1 W an early decision needs
        acc.add_battery(BatterySample(0.1 * k, 11.5, 0.02, float('nan')))
    assert acc.sign_ is None
    for k in range(3, 30):
        acc.add_battery(BatterySample(0.1 * k, 11.5, -0.8, float('nan')))
    assert acc.sign_ == -1.0


def test_millivolts_and_milliamps_under_one_amp(tmp_path):
    write_bag(tmp_path / 'bag', milli=True)  # 11500 mV, about 780 mA
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    np.testing.assert_allclose(run.power_in_w, P0_W, rtol=3e-3)
    assert any('voltage and current in milli-units' in n for n in run.extra['notes'])
    # millivolts beside amps stay amps: the power decides
    assert milli_factors(11800.0, 20.0) == (1e-3, 1.0)
    assert milli_factors(11800.0, 0.9) == (1e-3, 1.0)
    assert milli_factors(11800.0, 900.0) == (1e-3, 1e-3)
    assert milli_factors(11.8, 900.0) == (1.0, 1.0)
    assert milli_factors(11.8, 9000.0) == (1.0, 1e-3)


def test_joints_without_effort_interface_keep_the_others_power(tmp_path):
    truth = write_bag(tmp_path / 'bag', nan_effort_joints=(0, 3, 6, 9))
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    np.testing.assert_allclose(run.power_out_w, _pout(truth), rtol=0.03)
    coxae = ', '.join(truth['joints'][i] for i in (0, 3, 6, 9))
    assert any(f'no finite effort * velocity on joint(s) {coxae}' in n
               for n in run.extra['notes'])


def test_sporadic_nan_velocity_loses_only_those_samples(tmp_path):
    truth = write_bag(tmp_path / 'bag', nan_velocity_every=40)
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    np.testing.assert_allclose(run.power_out_w, _pout(truth), rtol=0.03)
    assert any('non-finite effort or velocity in some samples' in n and
               truth['joints'][1] in n for n in run.extra['notes'])


def test_negative_input_power_is_noted(tmp_path):
    write_bag(tmp_path / 'bag')  # ROS convention
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0, current_sign='positive_discharge')
    assert run.power_in_w < 0
    assert any('negative mean input power' in n and '--current-sign' in n
               for n in run.extra['notes'])
    # the sign is the problem, not the efforts: they are not blamed (P_out kept)
    assert implausible_effort_power(run.power_out_w, run.power_in_w, 0.0) == ''
    assert implausible_effort_power(run.power_out_w, 0.5 * run.power_out_w, 0.0) != ''


def test_odometry_twist_only_gives_the_speed(tmp_path):
    # a schedule without a step length (clock-driven) does not know the speed: odometry does
    write_bag(tmp_path / 'bag', odom_twist_only=True, step_length_m=0.0)
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    np.testing.assert_allclose(run.speed_mps, ODOM_SPEED_MPS, rtol=1e-6)
    assert run.extra['speed_source'] == 'odometry_twist'
    assert any('/odom twist' in n for n in run.extra['notes'])


def test_silent_battery_topic_is_named(tmp_path):
    write_bag(tmp_path / 'bag', battery=False)
    with pytest.raises(BagContentError, match='/battery_state has no messages'):
        read_robot_bag(tmp_path / 'bag', mass_kg=2.0)


def test_windows_across_a_recording_gap_are_left_out(tmp_path):
    write_bag(tmp_path / 'bag', duration_s=16.0, gap_s=(6.1, 9.1))
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    # whole 2 s cycles of P0 + 1.5 sin: the interpolation across the gap would bias P_in
    np.testing.assert_allclose(run.power_in_w, P0_W, rtol=3e-3)
    for d in run.extra['windows']:
        assert not (d.t_end_s - d.window_s < 6.1 and d.t_end_s > 6.2), d


def test_residual_reader_drops_bad_messages(tmp_path):
    """A NaN gait period and a NaN battery voltage: dropped with a note by the residual loop's
    reader, as by the energy reader and the live nodes (it raised ValueError)."""
    from hexapod_common.testbags import rewrite_bag
    from hexapod_energy.residuals import read_residual_run

    write_bag(tmp_path / 'bag')
    count = {'/gait/phase': 0, '/battery_state': 0}

    def spoil(topic, msg):
        if topic in count:
            count[topic] += 1
            if count[topic] == 7:
                if topic == '/gait/phase':
                    msg.period = float('nan')
                else:
                    msg.voltage = float('nan')

    rewrite_bag(tmp_path / 'bag', tmp_path / 'bad', spoil)
    run = read_residual_run(tmp_path / 'bad')
    notes = ' '.join(run.notes)
    assert '1 /gait/phase message(s) dropped' in notes and 'period' in notes
    assert '1 /battery_state message(s) dropped' in notes


def test_bench_bag_given_as_robot_is_refused(tmp_path):
    """A single-leg bench bag given as --robot gave 'runs' of a one-legged tripod (exit 0)."""
    from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
    from hexapod_bench_drivers.sim_bag import write_trace

    write_trace(simulate_bench(BenchPlan(loads_kg=(0.0,), frequencies_hz=(0.0, 1.0),
                                         walk_s=3.0), seed=1), tmp_path / 'bench')
    with pytest.raises(BagContentError, match='single-leg bench bag.*--bench'):
        read_robot_bag(tmp_path / 'bench', mass_kg=2.0)


def test_interrupt_is_said(capsys):
    """Ctrl-C: one line and exit 130 (it exited 130 in silence)."""
    import argparse

    from hexapod_common.analyze_cli import _run

    def boom(_args):
        raise KeyboardInterrupt

    assert _run(argparse.Namespace(func=boom, command='slip')) == 130
    assert 'interrupted' in capsys.readouterr().err
