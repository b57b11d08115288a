"""An outside review of the model side for other gaits and leg counts: the recommendation
and the sweeps never price a schedule the robot cannot walk as if it could (a whole side in
swing, no leg on the ground), the recommender's grid is checked up front, and the sweeps'
optimal points name their units."""

from __future__ import annotations

import pytest

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.recommend import infeasible_schedule, lifted_sides, recommend_gait
from hexapod_energy.sweeps import SweepSpec, standard_sweeps, sweep_curve
from hexapod_gait.config import min_supporting_per_side
from hexapod_gait.gait import make_gait

from test_energy_sweeps import Phase, opm  # noqa: F401  (the module fixture)


@pytest.mark.parametrize('legs', [6, 8, 12])
def test_the_recommendation_keeps_a_leg_down_on_each_side(opm, legs) -> None:  # noqa: F811
    """At 0.1 m/s a wave at beta 0.55 (three legs down, a whole side in swing, refused by
    gait_scheduler) won over the ripple of equal cost by search order. Now such a gait is
    rejected as 'support'."""
    rec = recommend_gait(Phase(), opm, speed_mps=0.1, leg_count=legs)
    b = rec.best
    gait = make_gait(b.gait, leg_count=legs, duty_factor=b.duty_factor,
                     period_s=b.period_s, step_length_m=b.step_length_m)
    assert min(min_supporting_per_side(gait).values()) >= 1, b
    assert gait.min_supporting_legs() >= min(3, legs // 2)


def test_a_wave_lifting_a_side_is_named_for_robot_runs_and_sweeps(opm) -> None:  # noqa: F811
    wave = make_gait('wave', leg_count=6, duty_factor=0.55, period_s=2.5, step_length_m=0.14)
    assert lifted_sides(wave) and 'side L/R' in lifted_sides(wave)[0]
    assert any('in swing at once' in w for w in infeasible_schedule(wave))
    ripple = make_gait('ripple', leg_count=6, duty_factor=0.55, period_s=2.5,
                       step_length_m=0.14)
    assert lifted_sides(ripple) == [] and infeasible_schedule(ripple) == []
    # the paper's Fig. 3C wave at beta 0.5 is still drawn, marked not walkable
    spec = next(s for s in standard_sweeps(6)['gait_type'] if s.label == 'wave beta 0.5')
    d = sweep_curve(spec, Phase(), opm, n_speeds=4).to_dict()
    assert 'in swing at once' in d['not_walkable']
    tripod = sweep_curve(SweepSpec('t', 'tripod', 6, 0.5), Phase(), opm, n_speeds=4)
    assert tripod.to_dict()['not_walkable'] == ''


def test_a_sweep_with_a_flight_phase_is_refused(opm) -> None:  # noqa: F811
    """A tripod at beta 0.3 (no leg down 40 % of the cycle) read CoT/M 27.7 J/(m kg), the
    lowest of any curve: Eq. 1 carried no weight while airborne."""
    with pytest.raises(InvalidInputError, match='no leg on the ground 40 %'):
        sweep_curve(SweepSpec('tripod beta 0.3', 'tripod', 6, 0.3), Phase(), opm, n_speeds=4)


def test_the_optimal_points_name_their_units(opm) -> None:  # noqa: F811
    pts = sweep_curve(SweepSpec('t', 'tripod', 6, 0.5), Phase(), opm,
                      n_speeds=4).optimal_points()
    assert {k: v['unit'] for k, v in pts.items()} == {
        'max_power_out': 'W', 'min_cot_per_mass': 'J/(m kg)', 'max_efficiency': 'fraction'}


@pytest.mark.parametrize('kw, match', [
    ({'step_lengths_m': (0.0,)}, 'step lengths must be finite and > 0'),
    ({'step_lengths_m': (0.0, 0.1)}, 'step lengths must be finite and > 0'),
    ({'step_lengths_m': (-0.1,)}, 'step lengths'),
    ({'duty_factors': (1.0,)}, r'duty factors must lie in \(0, 1\)'),
    ({'duty_factors': (0.5, 1.2)}, 'duty factors'),
    ({'duty_factors': ()}, 'no duty factor'),
])
def test_the_recommenders_grid_is_checked_up_front(opm, kw, match) -> None:  # noqa: F811
    """A step of 0 had been called 'not gaits for this leg count', and beside valid values
    dropped without a word."""
    with pytest.raises(InvalidInputError, match=match):
        recommend_gait(Phase(), opm, speed_mps=0.1, leg_count=8, **kw)
