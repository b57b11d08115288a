"""The actuator limits belong to the leg they were measured on (``ActuatorLimits.measured_on``).

AntBot's AX-18A limits (swing >= 0.16 s, stance >= 0.15 s) were measured on AntBot's leg
walking the 100 mm, 40 mm bench step. Another leg's step was scaled against that same leg's
own 100 mm path, so at 100 mm every leg kept AntBot's limits, although a PhantomX-like leg
(52/66/133 mm) moves its joints 12 % further in stance and 15 % further in swing there: it
was allowed 0.60 m/s where its servos reach 0.54 m/s, and a longer leg (50/120/200 mm), whose
joints move less, was held to limits scaled from its own short path (160 mm steps: 0.61 m/s
where 0.87 m/s is within the servos' speed). Now every user (gait node, sequencer,
``hexapod-sim``, ``energy``) scales the limits against the reference leg's bench path; limits
a user measured on their own leg (``--limits`` / ``-p limits`` / ``min_swing``, ``min_stance``
with a leg file) are that leg's.
"""

from __future__ import annotations

import dataclasses
import json
import types

import pytest

from hexapod_bench_drivers.sequencer import PlanError, load_plan
from hexapod_bench_drivers.sim_cli import _infeasible
from hexapod_energy.leg_description import load_leg_description
from hexapod_energy.prediction import geometry_limits
from hexapod_gait.config import build_gait
from hexapod_gait.errors import InfeasibleGaitError
from hexapod_gait.feasibility import ANTBOT_LIMITS, ActuatorLimits, max_speed_mps
from hexapod_gait.gait import make_gait
from hexapod_gait.gait_node import GaitParams, gait_from_params
from hexapod_gait.leg_file import read_leg_file
from hexapod_gait.step_limits import limits_for_step

PHANTOMX = """name: PhantomX-like
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.060, 0.070, 0.045]
neutral_tip_m: [0.14, 0.0, -0.10]
"""
LONG = """name: BigLeg
a_m: [0.05, 0.12, 0.20]
link_masses_kg: [0.06, 0.12, 0.08]
neutral_tip_m: [0.20, 0.0, -0.14]
"""


def _write(tmp_path_factory, name: str, text: str):
    path = tmp_path_factory.mktemp('leg') / f'{name}.yaml'
    path.write_text(text, encoding='utf8')
    return path


@pytest.fixture(scope='module')
def px_path(tmp_path_factory):
    return _write(tmp_path_factory, 'phantomx', PHANTOMX)


@pytest.fixture(scope='module')
def px(px_path):
    return read_leg_file(px_path)


@pytest.fixture(scope='module')
def big(tmp_path_factory):
    return read_leg_file(_write(tmp_path_factory, 'big', LONG))


def _on(leg) -> dict:
    return {'kinematics': leg.kinematics(), 'neutral_tip_m': leg.neutral_tip_m}


def test_antbots_limits_are_antbots_leg_at_the_bench_step() -> None:
    from hexapod_gait.feasibility import ANTBOT_BENCH, LimitsReference

    assert ANTBOT_LIMITS.measured_on == ANTBOT_BENCH == LimitsReference()
    assert ANTBOT_BENCH.step_m == (0.10, 0.04) and ActuatorLimits() == ANTBOT_LIMITS
    # AntBot unchanged: the bench step keeps the limits themselves, 140 mm as before
    assert limits_for_step(ANTBOT_LIMITS, 0.5, 0.10, 0.04) is ANTBOT_LIMITS
    lim = limits_for_step(ANTBOT_LIMITS, 0.5, 0.14, 0.04)
    assert (lim.min_swing_s, lim.min_stance_s) == pytest.approx((0.1920, 0.2214), abs=5e-4)


def test_another_leg_at_100_mm_needs_its_own_joint_path(px) -> None:
    """The PhantomX-like leg at the 100 mm step: AntBot's limits before (ratio 1.0)."""
    for beta in (0.5, 0.7):
        lim = limits_for_step(ANTBOT_LIMITS, beta, 0.10, 0.04, **_on(px))
        assert lim.min_stance_s / 0.15 == pytest.approx(1.120, abs=2e-3)
        assert 1.150 <= lim.min_swing_s / 0.16 <= 1.156
        assert lim.max_step_frequency_hz == 3.0
    lim = limits_for_step(ANTBOT_LIMITS, 0.5, 0.10, 0.04, **_on(px))
    assert (lim.min_swing_s, lim.min_stance_s) == pytest.approx((0.1846, 0.1680), abs=5e-4)
    assert max_speed_mps(0.5, 0.10, lim) == pytest.approx(0.5416, abs=5e-4)   # was 0.60
    # 140 mm on that leg: against AntBot's 100 mm path (0.197 s and 0.229 s before)
    lim = limits_for_step(ANTBOT_LIMITS, 0.5, 0.14, 0.04, **_on(px))
    assert (lim.min_swing_s, lim.min_stance_s) == pytest.approx((0.2271, 0.2570), abs=5e-4)


def test_a_longer_leg_is_held_to_its_joint_speeds_not_its_own_bench_path(big) -> None:
    """The 50/120/200 mm leg's joints travel less than AntBot's: at 100 mm it keeps the
    limits (a shorter path never lowers them), a 160 mm step needs stance >= 0.185 s (0.261 s
    before, scaled from its own 100 mm path)."""
    assert limits_for_step(ANTBOT_LIMITS, 0.5, 0.10, 0.04, **_on(big)) is ANTBOT_LIMITS
    lim = limits_for_step(ANTBOT_LIMITS, 0.5, 0.16, 0.04, **_on(big))
    assert (lim.min_swing_s, lim.min_stance_s) == pytest.approx((0.16, 0.1851), abs=5e-4)
    assert max_speed_mps(0.5, 0.16, lim) == pytest.approx(0.8645, abs=5e-4)   # was 0.614
    # 0.8 m/s on 160 mm steps: the gait node refused it on this leg, it is within its servos
    g = build_gait('tripod', speed_mps=0.8, step_length_m=0.16, step_height_m=0.04,
                   **_on(big))
    assert g.period_s == pytest.approx(0.4)


def test_limits_measured_on_the_users_leg_are_that_legs(px) -> None:
    from hexapod_gait.step_limits import measured_on_leg

    own = measured_on_leg(ANTBOT_LIMITS, px)
    assert own.measured_on.name == 'PhantomX-like' and own.measured_on.step_m == (0.1, 0.04)
    assert (own.min_swing_s, own.min_stance_s) == (0.16, 0.15)
    # on the leg they were measured on: the bench step keeps them, 140 mm scales by its path
    assert limits_for_step(own, 0.5, 0.10, 0.04, **_on(px)) is own
    lim = limits_for_step(own, 0.5, 0.14, 0.04, **_on(px))
    assert (lim.min_swing_s, lim.min_stance_s) == pytest.approx((0.1967, 0.2292), abs=5e-4)
    # on AntBot's leg (a shorter joint path than the PhantomX-like leg's 100 mm): kept
    assert limits_for_step(own, 0.5, 0.10, 0.04) is own
    # measured at another step: that step keeps them
    at80 = measured_on_leg(ANTBOT_LIMITS, None, (0.08, 0.04))
    assert at80.measured_on.name == "AntBot's leg"
    assert limits_for_step(at80, 0.5, 0.08, 0.04) is at80
    assert limits_for_step(at80, 0.5, 0.10, 0.04).min_stance_s > 0.15


def test_the_gait_node_refuses_what_the_leg_cannot_walk_at_100_mm(px) -> None:
    """0.58 m/s on the default 100 mm step (T 0.345 s, swing 0.172 s): AntBot's leg walks
    it; the PhantomX-like leg needs 0.185 s, unless the limits were measured on it."""
    p = GaitParams(speed=0.58)
    assert gait_from_params(p).period_s == pytest.approx(0.1 / (0.5 * 0.58))
    with pytest.raises(InfeasibleGaitError, match='maximum speed is 0.54'):
        gait_from_params(p, px)
    with pytest.raises(InfeasibleGaitError,
                       match=r'swing 0.172 s below the 0.185 s a 100 mm step needs.*'
                             r"for the 100 mm bench step of AntBot's leg"):
        gait_from_params(GaitParams(period=0.345), px)
    assert gait_from_params(p, px, limits_on_leg=True).period_s == pytest.approx(0.3448,
                                                                                abs=1e-4)


def test_the_sequencer_and_the_simulator_check_the_same_rule(px) -> None:
    plan = {'loads_kg': [0.0], 'frequencies_hz': [0.0, 2.9], 'duty_factors': [0.5],
            'step_lengths_m': [0.10], 'step_height_m': 0.04, 'walk_duration_s': 10.0,
            'temperature_gate_c': 26.0, 'temperature_tolerance_c': 1.0}
    assert load_plan(plan).sessions                      # AntBot's leg
    with pytest.raises(PlanError, match='0.185 s a 100 mm step needs'):
        load_plan(plan, leg=px)
    gait = make_gait('tripod', period_s=0.345, step_length_m=0.10, step_height_m=0.04)
    assert _infeasible(gait) == []
    why = _infeasible(gait, leg=px)
    assert why and 'swing' in why[0] and 'swing >= 0.185 s' in why[-1]
    # an AX-12A: AntBot's limits for that servo, on the PhantomX-like leg's path
    slow = make_gait('tripod', period_s=0.6, step_length_m=0.10, step_height_m=0.04)
    assert _infeasible(slow, 'ax12a') == []
    assert 'swing >= 0.304 s' in _infeasible(slow, 'ax12a', leg=px)[-1]


def test_energy_scales_the_limits_on_the_robots_leg(px_path) -> None:
    """``geometry_limits`` (sweeps, recommendation, robot runs): the robot's leg against the
    limits' reference, whatever step the energy bench walked."""
    from hexapod_energy.descriptors import DescriptorAccumulator
    from hexapod_energy.sweeps import SweepSpec, sweep_curve

    leg = load_leg_description(px_path)
    gait = make_gait('tripod', period_s=0.345, step_length_m=0.10, step_height_m=0.04)
    model = types.SimpleNamespace(bench_step_=(0.10, 0.04), bench_leg_=leg)
    lim = geometry_limits(model, gait, ANTBOT_LIMITS)
    assert (lim.min_swing_s, lim.min_stance_s) == pytest.approx((0.1846, 0.1680), abs=5e-4)
    from hexapod_gait.step_limits import measured_on_leg

    assert geometry_limits(model, gait, measured_on_leg(ANTBOT_LIMITS, leg)).min_swing_s == 0.16
    # a bench that walked 80 mm does not move AntBot's limits off their 100 mm step
    antbot_80 = types.SimpleNamespace(bench_step_=(0.08, 0.04), bench_leg_=None)
    assert geometry_limits(antbot_80, gait, ANTBOT_LIMITS) is ANTBOT_LIMITS
    # the sweeps' top speed of the PhantomX-like robot (tripod, beta 0.5, 100 mm): 0.60 before
    from test_energy_sweeps import Phase, StubTrajectory

    from hexapod_energy.prediction import OutputPowerModel

    phase = Phase()
    phase.bench_step_, phase.bench_leg_ = (0.10, 0.04), leg
    curve = sweep_curve(SweepSpec('t', 'tripod', 6, 0.5), phase,
                        OutputPowerModel(trajectory_factory=StubTrajectory, n_samples=16),
                        n_speeds=4)
    assert curve.speeds_mps[-1] == pytest.approx(0.5416, abs=5e-4)
    # the live monitor: AntBot's limits on this leg, or -p limits measured on it
    acc = DescriptorAccumulator(mass_kg=2.237, leg=leg)
    acc.add_gait_phase(_phase(gait))
    assert acc.infeasible_ and 'swing' in acc.infeasible_[0][1][0]
    own = DescriptorAccumulator(mass_kg=2.237, leg=leg,
                                limits=measured_on_leg(ActuatorLimits(), leg))
    own.add_gait_phase(_phase(gait))
    assert own.infeasible_ == []


def _phase(gait):
    import numpy as np

    from hexapod_common.conversions import GaitPhaseSample

    return GaitPhaseSample(t_s=0.0, gait='tripod', period_s=gait.period_s,
                           duty_factor=gait.duty_factor, step_length_m=gait.step_length_m,
                           step_height_m=gait.step_height_m, sweep_angle_rad=0.0,
                           leg_offset_rad=0.0, cycle_phase=0.0, leg_names=gait.leg_names,
                           phase_offsets=np.asarray(gait.phase_offsets),
                           in_stance=np.zeros(6, bool), supporting_legs=3)


def test_energy_limits_given_with_a_leg_are_that_legs(px_path, tmp_path, capsys) -> None:
    """``hexapod-analyze energy --leg``: a PhantomX-like robot run at 0.58 m/s on 100 mm steps
    is infeasible under AntBot's servo limits (it was not); ``--limits`` measured on that leg
    accept it."""
    from hexapod_bench_drivers.sim_cli import main as sim_main
    from hexapod_energy.cli import _actuator_limits
    from hexapod_energy.cli import main as energy_main

    bag = tmp_path / 'r'
    assert sim_main(['robot', '--duration', '2', '--no-progress', '--out', str(bag), '--leg',
                     str(px_path), '--period', '0.345', '--allow-infeasible']) == 0
    capsys.readouterr()
    for extra, infeasible in (([], True), (['--limits', '0.16', '0.15', '3'], False)):
        out = tmp_path / f'e{len(extra)}'
        assert energy_main(['--robot', str(bag), '--leg', str(px_path), '--out', str(out),
                            '--no-progress', *extra]) == 0
        doc = json.loads((out / 'energy.json').read_text())
        bad = [w for w in doc.get('warnings', []) if 'infeasible schedule' in w]
        assert bool(bad) == infeasible, bad
        if bad:
            assert 'swing lasts 0.1725 s < minimum 0.1846 s' in bad[0]
    leg = load_leg_description(px_path)
    lim, source = _actuator_limits(types.SimpleNamespace(limits=[0.16, 0.15, 3.0]), leg)
    assert lim.measured_on.name == 'PhantomX-like' and source == '--limits'
    lim, source = _actuator_limits(types.SimpleNamespace(limits=None), leg)
    assert lim is ANTBOT_LIMITS and "AntBot's leg" in source


def test_a_limits_reference_is_checked() -> None:
    from hexapod_gait.feasibility import ANTBOT_BENCH, LimitsReference

    with pytest.raises(ValueError, match='measured_on'):
        ActuatorLimits(0.16, 0.15, 3.0, 'AntBot')
    with pytest.raises(ValueError, match='step_length_m'):
        LimitsReference(step_length_m=-0.1)
    assert dataclasses.replace(ANTBOT_LIMITS, min_swing_s=0.2).measured_on is ANTBOT_BENCH
