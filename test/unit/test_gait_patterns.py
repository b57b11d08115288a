"""Gait patterns and the exact number of supporting legs L(t) (issue 3, items 1 and 2)."""

from __future__ import annotations

import importlib
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from hexapod_gait.errors import InvalidGaitError
from hexapod_gait.gait import (
    GaitPattern,
    carried_mass_per_leg_kg,
    make_gait,
    typical_duty_factor,
)
from hexapod_gait.legs import all_joint_names, joint_names, leg_names

CORE_MODULES = (
    'hexapod_gait.errors', 'hexapod_gait.legs', 'hexapod_gait.gait', 'hexapod_gait.feasibility',
    'hexapod_gait.kinematics', 'hexapod_gait.trajectory', 'hexapod_gait.buehler',
    'hexapod_gait.scheduler',
)


def test_core_modules_import_without_rclpy():
    code = (
        'import sys\n'
        'class Block:\n'
        '    def find_spec(self, name, path=None, target=None):\n'
        "        if name.split('.')[0] in ('rclpy', 'hexapod_interfaces', 'sensor_msgs'):\n"
        "            raise ImportError('blocked ' + name)\n"
        'sys.meta_path.insert(0, Block())\n'
        + ''.join(f'import {m}\n' for m in CORE_MODULES)
        + "assert 'rclpy' not in sys.modules\n"
    )
    subprocess.run([sys.executable, '-c', code], check=True)


def test_every_core_module_has_all():
    for name in CORE_MODULES:
        mod = importlib.import_module(name)
        assert mod.__all__, name
        for attr in mod.__all__:
            assert hasattr(mod, attr), (name, attr)


def test_leg_and_joint_names():
    assert leg_names(6) == ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    assert leg_names(4) == ('L1', 'L2', 'R1', 'R2')
    assert len(leg_names(8)) == 8
    assert joint_names('L1') == ('L1_coxa', 'L1_femur', 'L1_tibia')
    assert joint_names('R3', dof=1) == ('R3_hip',)
    assert all_joint_names(('L1', 'R1'), 1) == ('L1_hip', 'R1_hip')
    with pytest.raises(InvalidGaitError, match='even'):
        leg_names(5)
    with pytest.raises(InvalidGaitError, match='dof'):
        joint_names('L1', dof=2)


def offsets(g: GaitPattern) -> dict[str, float]:
    return dict(zip(g.leg_names, g.phase_offsets))


def test_tripod_offsets_and_exactly_three_supporting_legs():
    g = make_gait('tripod', duty_factor=0.5, period_s=0.8)
    assert offsets(g) == {'L1': 0.0, 'R2': 0.0, 'L3': 0.0, 'R1': 0.5, 'L2': 0.5, 'R3': 0.5}
    bp, L = g.support_profile()
    assert_array_equal(L, [3, 3])
    assert g.min_supporting_legs() == 3 and g.max_supporting_legs() == 3
    # dense grid including every boundary instant exactly
    t = np.concatenate([np.linspace(0.0, 5 * 0.8, 20001), 0.8 * np.arange(0, 10) / 2])
    assert_array_equal(g.supporting_legs(t), 3)


@settings(max_examples=300, deadline=None)
@given(t=st.floats(min_value=-1e4, max_value=1e4, allow_nan=False))
def test_tripod_half_is_three_at_any_time(t):
    g = make_gait('tripod', duty_factor=0.5, period_s=1.0 / 3.0)
    assert g.supporting_legs(t)[0] == 3


def test_named_offsets_for_six_legs():
    wave = make_gait('wave')
    assert_allclose([offsets(wave)[k] for k in ('L3', 'L2', 'L1', 'R3', 'R2', 'R1')],
                    np.arange(6) / 6)
    tetra = make_gait('tetrapod')
    o = offsets(tetra)
    assert o['L3'] == o['R1'] == 0.0
    assert_allclose([o['L2'], o['R3']], [1 / 3, 1 / 3])
    assert_allclose([o['L1'], o['R2']], [2 / 3, 2 / 3])
    ripple = offsets(make_gait('ripple'))
    assert_allclose([ripple['L3'], ripple['L2'], ripple['L1']], [0, 1 / 3, 2 / 3])
    assert_allclose([ripple['R3'], ripple['R2'], ripple['R1']], [0.5, 5 / 6, 1 / 6])
    quad = offsets(make_gait('alternating', leg_count=4))
    assert quad == {'L1': 0.0, 'R2': 0.0, 'L2': 0.5, 'R1': 0.5}


@pytest.mark.parametrize('name, n, expected', [
    ('wave', 6, 5), ('tetrapod', 6, 4), ('ripple', 6, 4), ('alternating', 4, 2),
    ('alternating', 8, 4), ('wave', 8, 7), ('wave', 4, 3),
])
def test_typical_duty_factor_gives_constant_support(name, n, expected):
    g = make_gait(name, leg_count=n, duty_factor=typical_duty_factor(name, n))
    assert g.min_supporting_legs() == expected == g.max_supporting_legs()


def test_wave_swings_one_leg_at_a_time():
    g = make_gait('wave', duty_factor=5 / 6)
    t = np.linspace(0, 3, 30001)
    assert (~g.stance_mask(t)).sum(axis=1).max() == 1
    # the paper's rounded 0.83 leaves swings overlapping for 0.0033 of a cycle
    g83 = make_gait('wave', duty_factor=0.83)
    bp, L = g83.support_profile()
    assert g83.min_supporting_legs() == 4 and g83.max_supporting_legs() == 5
    assert_allclose(np.sum(np.diff(np.append(bp, 1.0))[L == 4]), 6 * (5 / 6 - 0.83), rtol=1e-9)


def test_tripod_short_duty_factor_has_flight_and_long_has_six():
    assert make_gait('tripod', duty_factor=0.3).min_supporting_legs() == 0
    g = make_gait('tripod', duty_factor=0.7)
    bp, L = g.support_profile()
    assert_allclose(bp, [0.0, 0.2, 0.5, 0.7])
    assert_array_equal(L, [6, 3, 6, 3])


gait_strategy = st.one_of(
    st.builds(
        lambda name, k, beta, T: make_gait(name, leg_count=2 * k, duty_factor=beta, period_s=T),
        st.sampled_from(['alternating', 'wave', 'ripple', 'tetrapod']),
        st.integers(1, 5),
        st.floats(0.01, 0.99),
        st.floats(0.05, 10.0),
    ),
    st.integers(1, 5).flatmap(lambda k: st.builds(
        lambda th, beta: make_gait('custom', leg_count=2 * k, duty_factor=beta,
                                   phase_offsets=th),
        st.lists(st.floats(0.0, 0.999999), min_size=2 * k, max_size=2 * k),
        st.floats(0.01, 0.99),
    )),
)


@settings(max_examples=300, deadline=None)
@given(g=gait_strategy)
def test_mean_supporting_legs_is_n_beta(g):
    assert_allclose(g.mean_supporting_legs(), g.leg_count * g.duty_factor, rtol=1e-9)
    bp, L = g.support_profile()
    assert bp[0] == 0.0 and np.all(np.diff(bp) > 0) and bp[-1] < 1.0
    assert g.min_supporting_legs() == L.min() and g.max_supporting_legs() == L.max()


@settings(max_examples=100, deadline=None)
@given(g=gait_strategy)
def test_profile_agrees_with_stance_mask_inside_intervals(g):
    bp, L = g.support_profile()
    ends = np.append(bp[1:], 1.0)
    wide = (ends - bp) > 1e-9
    mid = 0.5 * (bp + ends)[wide]
    assert_array_equal(g.supporting_legs(mid * g.period_s), L[wide])


def test_leg_phase_and_stance_semantics():
    g = make_gait('custom', leg_count=2, duty_factor=0.25, period_s=2.0,
                  phase_offsets=[0.1, 0.6])
    phi = g.leg_phase([0.2, 1.3])  # cycle phases 0.1 and 0.65
    assert_allclose(phi, [[0.0, 0.5], [0.55, 0.05]], atol=1e-15)
    assert_array_equal(g.stance_mask([0.2, 1.3]), [[True, False], [False, True]])
    assert np.all(g.leg_phase(np.linspace(-10, 10, 1001)) < 1.0)


def test_speed_and_times():
    g = make_gait('tripod', duty_factor=0.6, period_s=0.5, step_length_m=0.12)
    assert_allclose(g.speed_mps, 0.12 / 0.3)
    assert_allclose([g.stance_time_s, g.swing_time_s, g.step_frequency_hz], [0.3, 0.2, 2.0])
    assert g.with_changes(duty_factor=0.5).duty_factor == 0.5


def test_carried_mass_per_leg():
    m = carried_mass_per_leg_kg(2.183, 0.166, [3, 6, 0])
    assert_allclose(m[:2], [(2.183 - 0.166 * 3) / 3, (2.183 - 0.166 * 6) / 6])
    assert np.isinf(m[2])


@pytest.mark.parametrize('kwargs, match', [
    (dict(name='gallop'), 'gait name'),
    (dict(name='tripod', leg_count=4), "needs 6 legs"),
    (dict(name='tripod', duty_factor=1.0), 'duty_factor'),
    (dict(name='tripod', period_s=0.0), 'period_s'),
    (dict(name='custom'), 'phase_offsets'),
    (dict(name='wave', phase_offsets=[0] * 6), "only accepted with gait 'custom'"),
    (dict(name='custom', leg_count=4, phase_offsets=[0, 0.5]), 'one value per leg'),
])
def test_bad_gaits_are_refused_with_reason(kwargs, match):
    name = kwargs.pop('name')
    with pytest.raises(InvalidGaitError, match=match):
        make_gait(name, **kwargs)
