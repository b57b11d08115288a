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
