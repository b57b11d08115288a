"""DescriptorAccumulator: P_out definition (positive joint power) and the Eq. 6 model fallback."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
from hexapod_energy.descriptors import (
    DescriptorAccumulator,
    gait_from_sample,
    joint_power_out_w,
    model_power_out,
)
from hexapod_energy.prediction import OutputPowerModel, RobotSpec

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
ROBOT_KG = 2.183


def _gait(t: float, period: float = 0.8) -> GaitPhaseSample:
    return GaitPhaseSample(
        t_s=t, gait='tripod', period_s=period, duty_factor=0.5, step_length_m=0.1,
        step_height_m=0.04, sweep_angle_rad=0.0, leg_offset_rad=0.0,
        cycle_phase=(t / period) % 1.0, leg_names=LEGS,
        phase_offsets=np.array([0.0, 0.5, 0.0, 0.5, 0.0, 0.5]),
        in_stance=np.ones(6, bool), supporting_legs=3)


def _feed(acc: DescriptorAccumulator, *, efforts: bool, period: float = 0.8) -> list:
    out = []
    rng = np.random.default_rng(0)
    for k in range(400):
        t = 0.01 * k
        out += acc.add_gait_phase(_gait(t, period))
        if efforts:
            acc.add_joint_state(JointStateSample(
                t, ('a', 'b'), np.zeros(2), np.array([1.0, -2.0]), np.array([0.5, 0.25])))
        else:
            acc.add_joint_state(JointStateSample(t, ('a', 'b'), rng.normal(size=2),
                                                 rng.normal(size=2), np.empty(0)))
        out += acc.add_battery(BatterySample(t, 12.0, -2.5, 25.0))
    return out


def test_joint_power_counts_positive_work_only() -> None:
    assert joint_power_out_w(np.array([1.0, -2.0, 3.0]), np.array([0.5, 0.25, -1.0])) == 0.5


@pytest.fixture(scope='module')
def opm() -> OutputPowerModel:
    return OutputPowerModel(robot=RobotSpec(mass_kg=ROBOT_KG), n_samples=100)


def test_model_fallback_without_efforts(opm) -> None:
    payload = 0.3
    acc = DescriptorAccumulator(mass_kg=ROBOT_KG + payload, current_sign='ros',
                                power_out_model=model_power_out(opm, robot_mass_kg=ROBOT_KG))
    windows = _feed(acc, efforts=False)
    assert len(windows) >= 3
    expected = opm.power_out_w(gait_from_sample(_gait(0.0)), payload_kg=payload)
    assert 0.1 < expected < 2.0  # positive joint power of AntBot at 0.25 m/s
    for d in windows:
        assert d.power_out_w == pytest.approx(expected, rel=1e-12)
        assert_allclose(d.power_in_w, 30.0, rtol=1e-12)
        assert d.efficiency == pytest.approx(expected / 30.0, rel=1e-12)


def test_efforts_win_in_auto_and_lose_in_model_mode(opm) -> None:
    model = model_power_out(opm, robot_mass_kg=ROBOT_KG)
    auto = _feed(DescriptorAccumulator(mass_kg=ROBOT_KG, current_sign='ros',
                                       power_out_model=model), efforts=True)
    assert all(d.power_out_w == pytest.approx(0.5) for d in auto)  # max(0.5,0)+max(-0.5,0)
    forced = _feed(DescriptorAccumulator(mass_kg=ROBOT_KG, current_sign='ros',
                                         power_out_model=model, power_out_source='model'),
                   efforts=True)
    expected = opm.power_out_w(gait_from_sample(_gait(0.0)), payload_kg=0.0)
    assert all(d.power_out_w == pytest.approx(expected, rel=1e-12) for d in forced)
    effort_only = _feed(DescriptorAccumulator(mass_kg=ROBOT_KG, current_sign='ros',
                                              power_out_model=model,
                                              power_out_source='effort'), efforts=False)
    assert all(d.power_out_w == 0.0 for d in effort_only)


def test_bad_power_out_source_is_named() -> None:
    with pytest.raises(ValueError, match='power_out_source'):
        DescriptorAccumulator(mass_kg=1.0, power_out_source='torque')


def test_auto_refuses_efforts_that_never_do_negative_work(opm) -> None:
    """AX-series 'effort' is the PWM duty times the stall torque: it carries the back-EMF, so it
    always has the velocity's sign and its effort x velocity is never negative (net / positive
    1.000 on the simulated AntBot, 7.1 W where the joints deliver 0.20 W). 'auto' then takes
    the Eq. 6 model and says why; 'effort' still reports the efforts as asked. Torques of a
    cyclic gait do negative work too and are kept."""
    model = model_power_out(opm, robot_mass_kg=ROBOT_KG)
    expected = opm.power_out_w(gait_from_sample(_gait(0.0)), payload_kg=0.0)

    def feed(acc: DescriptorAccumulator, duty_like: bool, amp: float = 1.0) -> list:
        out = []
        for k in range(400):
            t = 0.01 * k
            vel = np.array([np.cos(2 * np.pi * t / 0.8), np.sin(2 * np.pi * t / 0.8)])
            # a torque: a gravity-like offset plus a spring-like part (in quadrature with the
            # velocity), so the joint does positive and negative work over the cycle
            quad = np.array([np.sin(2 * np.pi * t / 0.8), -np.cos(2 * np.pi * t / 0.8)])
            eff = amp * (vel if duty_like else 0.3 + 0.5 * quad)
            out += acc.add_gait_phase(_gait(t))
            acc.add_joint_state(JointStateSample(t, ('a', 'b'), np.zeros(2), vel, eff))
            out += acc.add_battery(BatterySample(t, 12.0, -2.5, 25.0))
        return out

    torque = feed(DescriptorAccumulator(mass_kg=ROBOT_KG, power_out_model=model), False)
    assert len(torque) >= 3
    phi = np.linspace(0.0, 2 * np.pi, 100001)
    positive = 2 * np.mean(np.clip((0.3 + 0.5 * np.sin(phi)) * np.cos(phi), 0.0, None))
    for d in torque:
        assert not d.warnings
        assert d.power_out_w == pytest.approx(positive, rel=0.02)
        assert abs(d.joint_power_net_w) < 0.05 * d.power_out_w
    auto = feed(DescriptorAccumulator(mass_kg=ROBOT_KG, power_out_model=model), True)
    for d in auto:
        assert d.power_out_w == pytest.approx(expected, rel=1e-12)
        assert any('never do negative work' in w for w in d.warnings)
        assert d.joint_power_net_w == pytest.approx(1.0, rel=0.05)  # 2 x mean(v^2) = 1 W
    forced = feed(DescriptorAccumulator(mass_kg=ROBOT_KG, power_out_model=model,
                                        power_out_source='effort'), True)
    assert all(d.power_out_w == pytest.approx(1.0, rel=0.05) for d in forced)
    # above the input power (30 W here) and no model to fall back on: unknown, not 60+ W
    no_model = feed(DescriptorAccumulator(mass_kg=ROBOT_KG), False, amp=200.0)
    assert all(np.isnan(d.power_out_w) for d in no_model)
    assert all(any('not below P_in' in w for w in d.warnings) for d in no_model)


def test_joint_power_is_a_time_average_like_the_input_power() -> None:
    """A joint sampled twice as densely over half of each cycle: the plain mean of the samples
    read P_out +21 % (an outside review of the equations); each sample now stands for its
    time, and evenly spaced samples keep their plain mean."""
    from hexapod_energy.descriptors import _mean_joint_power_w

    def joint(t):
        return [(float(x), ('j',), np.array([1.0 + np.sin(2 * np.pi * x)]), False) for x in t]

    dense = np.sort(np.concatenate([np.arange(0, 0.5, 0.005), np.arange(0.5, 1.0, 0.01)]))
    assert _mean_joint_power_w(joint(dense)) == pytest.approx(1.0, abs=2e-3)
    even = np.arange(0, 1, 0.01)
    assert _mean_joint_power_w(joint(even)) == pytest.approx(
        float(np.mean(1.0 + np.sin(2 * np.pi * even))), rel=1e-12)
    # joints split over messages (another name set): each joint's own times
    split = joint(dense) + [(float(x), ('k',), np.array([2.0]), False) for x in even]
    assert _mean_joint_power_w(split) == pytest.approx(3.0, abs=2e-3)
