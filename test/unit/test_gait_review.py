"""Gait scheduler core after the outside review (FINDINGS G1, G2, G4)."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_gait.config import build_gait, check_static_support, min_supporting_per_side
from hexapod_gait.errors import HexapodGaitError, InfeasibleGaitError, InvalidGaitError
from hexapod_gait.gait import make_gait
from hexapod_gait.gait_node import GaitParams, gait_from_params
from hexapod_gait.scheduler import MIN_TRANSITION_CYCLES, GaitScheduler
from hexapod_common.node_utils import validate_params


@pytest.mark.parametrize('legs', [4, 6, 8])
def test_wave_at_half_duty_factor_loses_a_side_and_is_refused_live(legs):
    wave = make_gait('wave', leg_count=legs, duty_factor=0.5)      # still computable offline
    assert min(min_supporting_per_side(wave).values()) == 0
    with pytest.raises(InfeasibleGaitError, match='lifts every leg of side'):
        check_static_support(wave)
    check_static_support(make_gait('wave', leg_count=legs, duty_factor=1 - 1 / legs))
    check_static_support(make_gait('tetrapod', leg_count=legs, duty_factor=0.5))
    # The node's rules refuse it, with the wave's own duty factor in the reason.
    with pytest.raises(HexapodGaitError, match=f'1 - 1/n = {1 - 1 / legs:.4g}'):
        gait_from_params(GaitParams(gait='wave', leg_count=legs))
    # Offline analysis is unchanged.
    assert build_gait('wave', leg_count=legs, duty_factor=0.5, period_s=2.0).duty_factor == 0.5


def test_standing_needs_no_support_check_and_uses_the_period_even_in_speed_mode():
    g = gait_from_params(GaitParams(gait='wave', stand=True))
    assert g.step_length_m == 0.0 and g.step_height_m == 0.0
    g = gait_from_params(GaitParams(speed=0.3, step_length=0.0, step_height=0.0, period=1.5))
    assert g.step_length_m == 0.0 and g.period_s == 1.5


def test_transition_cycles_has_a_lower_bound():
    tripod = make_gait('tripod', period_s=1.0)
    with pytest.raises(InvalidGaitError, match=f'>= {MIN_TRANSITION_CYCLES:g}'):
        GaitScheduler(tripod, transition_cycles=0.001)
    sched = GaitScheduler(tripod)
    with pytest.raises(InvalidGaitError):
        sched.transition_cycles = 0.001
    with pytest.raises(Exception, match=f'must be >= {MIN_TRANSITION_CYCLES:g}'):
        validate_params(GaitParams, {'transition_cycles': 0.001})


def test_transition_at_the_lower_bound_keeps_joint_steps_small():
    tripod = make_gait('tripod', period_s=1.0)
    wave = make_gait('wave', duty_factor=5 / 6, period_s=1.0)
    sched = GaitScheduler(tripod, transition_cycles=MIN_TRANSITION_CYCLES)
    sched.set_gait(wave, 1.0)
    t = np.arange(1.0, 2.0, 0.01)
    q = np.array([sched.joint_targets(x)[1] for x in t])
    assert np.abs(np.diff(q, axis=0)).max() < 0.3       # 0.56 rad at transition_cycles 0.001


def test_standing_has_every_leg_in_stance():
    stand = make_gait('tripod', period_s=1.0, step_length_m=0.0, step_height_m=0.0)
    sched = GaitScheduler(stand)
    for t in np.linspace(0.0, 2.0, 41):
        st = sched.state(t)
        assert st.in_stance.all() and st.supporting_legs == 6
    # A walk that stands: legs cycle while moving, all in stance once settled.
    sched = GaitScheduler(make_gait('tripod', period_s=1.0))
    assert sched.state(0.75).supporting_legs == 3
    sched.set_gait(stand, 1.0)
    assert sched.state(sched.transition_end_s + 0.25).supporting_legs == 6
