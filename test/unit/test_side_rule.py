"""One whole-side rule (:func:`hexapod_gait.config.unsupported_sides`) for ``gait_scheduler``
(:func:`check_static_support`), ``hexapod-sim`` and the energy recommendation: the
simulator and the recommendation each had their own. The recommendation skipped stepping in
place (step length 0, height > 0), which lifts the legs all the same; the scheduler refused
every walking gait on 2 legs ('raise the duty factor to >= 1': a side of one leg is lifted in
every swing), which the simulator and the recommendation accepted."""

from __future__ import annotations

import pytest

from hexapod_gait.config import build_gait, check_static_support, unsupported_sides
from hexapod_gait.errors import InfeasibleGaitError


def _all_three(gait):
    from hexapod_bench_drivers.sim_cli import _infeasible
    from hexapod_energy.recommend import lifted_sides

    try:
        check_static_support(gait)
        scheduler = ''
    except InfeasibleGaitError as err:
        scheduler = str(err)
    sim = [w for w in _infeasible(gait) if 'lifts every leg' in w or 'flight' in w]
    return scheduler, sim, lifted_sides(gait)


def test_stepping_in_place_is_checked_by_all() -> None:
    gait = build_gait('wave', leg_count=6, duty_factor=0.5, step_length_m=0.0,
                      step_height_m=0.04)
    assert unsupported_sides(gait) == ['L', 'R']
    scheduler, sim, recommend = _all_three(gait)
    assert 'lifts every leg of side L/R' in scheduler and sim == [scheduler]
    assert recommend and 'side L/R' in recommend[0]


def test_two_legs_walk_without_the_side_rule_but_not_in_flight() -> None:
    walk = build_gait('alternating', leg_count=2, duty_factor=0.5)
    assert unsupported_sides(walk) == []
    assert _all_three(walk) == ('', [], [])
    hop = build_gait('alternating', leg_count=2, duty_factor=0.4)
    with pytest.raises(InfeasibleGaitError, match=r'flight phase.*>= 0\.5 on 2 legs$'):
        check_static_support(hop)


def test_standing_and_supported_gaits_pass_everywhere() -> None:
    for gait in (build_gait('wave', leg_count=6, duty_factor=0.5, step_length_m=0.0,
                            step_height_m=0.0),
                 build_gait('tripod', leg_count=6, duty_factor=0.5),
                 build_gait('wave', leg_count=8, duty_factor=0.875, period_s=2.0)):
        assert unsupported_sides(gait) == [] and _all_three(gait) == ('', [], [])
