"""Outside review: gaits the project calls infeasible (beyond the servo limits, or no leg on the
ground at some phase) were simulated by ``hexapod-sim robot`` and analysed by
``hexapod-analyze energy`` without a word (a wave at duty factor 0.1: CoT/M 29.0 J/(m kg),
better than any feasible gait)."""

from __future__ import annotations

import dataclasses
import json

import pytest

from hexapod_energy.recommend import infeasible_schedule


def _gait(name, **kw):
    from hexapod_gait.gait import make_gait
    return make_gait(name, **kw)


def test_infeasible_schedule_names_limits_and_airborne_phases() -> None:
    from hexapod_gait.feasibility import ActuatorLimits

    wave = infeasible_schedule(_gait('wave', duty_factor=0.1, period_s=1.0))
    assert any('stance lasts 0.1 s < minimum 0.15 s' in w for w in wave)
    assert any('no leg on the ground 40 % of the cycle' in w for w in wave)
    # within the limits but airborne: still infeasible
    slow = infeasible_schedule(_gait('wave', duty_factor=0.1, period_s=2.0))
    assert len(slow) == 1 and 'L(t) = 0' in slow[0]
    fast = infeasible_schedule(_gait('tripod', period_s=0.2222))
    assert len(fast) == 3 and any('4.5 Hz > maximum 3 Hz' in w for w in fast)
    assert infeasible_schedule(_gait('tripod', period_s=0.2222),
                               ActuatorLimits(0.1, 0.1, 5.0)) == []
    assert infeasible_schedule(_gait('tripod', period_s=1.0)) == []
    # L = 1, never airborne, but one side is all in swing (an outside review: such a wave
    # at beta 0.55 had been recommended)
    one = infeasible_schedule(_gait('wave', duty_factor=1 / 6, period_s=1.2))
    assert len(one) == 1 and 'side L/R is in swing at once' in one[0]
    # a RHex's clock (step length 0, flight phases when running) is not a stepping gait
    assert infeasible_schedule(_gait('buehler', duty_factor=0.3, period_s=0.3)) == []


def _sim(args, capsys):
    from hexapod_bench_drivers.sim_cli import main as sim_main
    rc = sim_main(['robot', '--duration', '2', '--no-progress', *args])
    return rc, capsys.readouterr().err


def test_sim_refuses_infeasible_gaits_unless_allowed(tmp_path, capsys) -> None:
    rc, err = _sim(['--out', str(tmp_path / 'w'), '--gait', 'wave', '--duty-factor', '0.1'],
                   capsys)
    assert rc == 2 and not (tmp_path / 'w').exists()
    assert 'infeasible' in err and 'L(t) = 0' in err and '--allow-infeasible' in err
    rc, err = _sim(['--out', str(tmp_path / 'f'), '--speed', '0.9'], capsys)
    assert rc == 2 and 'stance lasts 0.1111 s' in err and '4.5 Hz > maximum 3 Hz' in err
    rc, err = _sim(['--out', str(tmp_path / 'f'), '--speed', '0.9', '--allow-infeasible'],
                   capsys)
    assert rc == 0 and (tmp_path / 'f').is_dir() and 'warning' in err and 'infeasible' in err
    rc, err = _sim(['--out', str(tmp_path / 'ok'), '--speed', '0.6'], capsys)   # the limit
    assert rc == 0 and 'infeasible' not in err


def test_sim_limits_follow_the_servo_preset(tmp_path, capsys) -> None:
    """The simulator checked every servo preset against the AX-18A's limits: an AX-12A robot
    (59 rpm no-load against 97) was simulated at 0.5 m/s. The limits now scale with the
    preset's no-load speed."""
    from hexapod_bench_drivers.sim_cli import servo_limits
    from hexapod_gait.feasibility import ANTBOT_LIMITS

    assert servo_limits('ax18a') == ANTBOT_LIMITS
    ax12 = servo_limits('ax12a')
    assert ax12.min_swing_s == pytest.approx(0.16 * 97 / 59)
    assert ax12.max_step_frequency_hz == pytest.approx(3.0 * 59 / 97)
    rc, err = _sim(['--out', str(tmp_path / 'a'), '--speed', '0.5', '--servo', 'ax12a'],
                   capsys)
    assert rc == 2 and 'for ax12a servos' in err and 'swing >= 0.263 s' in err
    rc, err = _sim(['--out', str(tmp_path / 'b'), '--speed', '0.5'], capsys)
    assert rc == 0 and 'infeasible' not in err
    rc, err = _sim(['--out', str(tmp_path / 'c'), '--speed', '0.3', '--servo', 'ax12a'],
                   capsys)
    assert rc == 0 and 'infeasible' not in err
    rc, err = _sim(['--out', str(tmp_path / 'd'), '--servo', 'nosuch'], capsys)
    assert rc == 2 and 'nosuch' in err and 'Traceback' not in err


def test_energy_warns_on_an_infeasible_robot_run(tmp_path, capsys) -> None:
    from hexapod_energy.cli import main as energy_main

    assert _sim(['--out', str(tmp_path / 'bad'), '--gait', 'wave', '--duty-factor', '0.1',
                 '--period', '2', '--duration', '4', '--allow-infeasible'], capsys)[0] == 0
    assert _sim(['--out', str(tmp_path / 'good'), '--duration', '4'], capsys)[0] == 0
    out = tmp_path / 'e'
    assert energy_main(['--robot', str(tmp_path / 'bad'), str(tmp_path / 'good'),
                        '--robot-mass', '2.183', '--out', str(out), '--no-progress']) == 0
    doc = json.loads((out / 'energy.json').read_text())
    bad = [w for w in doc['warnings'] if 'infeasible schedule' in w]
    assert len(bad) == 1 and 'bad' in bad[0] and 'L(t) = 0' in bad[0]
    runs = {r['bag'].rsplit('/', 1)[-1]: r for r in doc['robot_runs']}
    assert any('infeasible schedule' in n for n in runs['bad']['notes'])
    assert not any('infeasible' in n for n in runs['good']['notes'])
    # --limits are the robot's: loose enough limits leave only the airborne phase
    out2 = tmp_path / 'e2'
    assert energy_main(['--robot', str(tmp_path / 'bad'), '--robot-mass', '2.183',
                        '--limits', '0.01', '0.01', '50', '--out', str(out2),
                        '--no-progress']) == 0
    doc2 = json.loads((out2 / 'energy.json').read_text())
    (w,) = [w for w in doc2['warnings'] if 'infeasible schedule' in w]
    assert 'L(t) = 0' in w and 'minimum' not in w


if __name__ == '__main__':
    raise SystemExit(pytest.main([__file__, '-q']))


def test_sim_and_energy_agree_on_other_step_geometries(tmp_path, capsys) -> None:
    """A review: the simulator checked AntBot's limits as phase durations whatever the step,
    energy scales them to the step's joint path (geometry_limits): 140 mm steps at 0.8 m/s
    were simulated and then called infeasible, 70 mm at beta 0.7 and 0.2 m/s refused and then
    called feasible. Both now read the limits on the step's own path; a shorter path keeps
    the bench's limits (a later review: unfloored, a 20 mm step walked 33 ms swings), so
    the 70 mm step's 0.15 s swing is refused by both."""
    from hexapod_energy.prediction import geometry_limits
    from hexapod_energy.recommend import infeasible_schedule
    from hexapod_gait.feasibility import ActuatorLimits
    from hexapod_gait.gait import make_gait

    rc, err = _sim(['--out', str(tmp_path / 'a'), '--speed', '0.8', '--step-length', '0.14'],
                   capsys)
    assert rc == 2 and 'on this step\'s joint path' in err
    rc, err = _sim(['--out', str(tmp_path / 'b'), '--speed', '0.2', '--duty-factor', '0.7',
                    '--step-length', '0.07'], capsys)
    assert rc == 2 and 'swing' in err
    gait = make_gait('tripod', duty_factor=0.7, period_s=0.5, step_length_m=0.07,
                     step_height_m=0.04)
    model = type('Bench', (), {'bench_step_': (0.1, 0.04)})()
    assert infeasible_schedule(gait, geometry_limits(model, gait, ActuatorLimits()))


def test_energy_without_a_bench_reads_the_limits_on_the_steps_path(tmp_path, capsys) -> None:
    """A review: without --bench (no fitted model) energy checked a robot run against the
    100 mm bench step's limits whatever its step, so a 140 mm tripod at T 0.4 s (stance 0.2 s,
    that step needs 0.221 s) passed while hexapod-sim and the gait node refuse it."""
    from hexapod_energy.cli import main as energy_main

    assert _sim(['--out', str(tmp_path / 'r'), '--period', '0.4', '--step-length', '0.14',
                 '--duration', '4', '--allow-infeasible'], capsys)[0] == 0
    out = tmp_path / 'e'
    assert energy_main(['--robot', str(tmp_path / 'r'), '--robot-mass', '2.183',
                        '--out', str(out), '--no-progress']) == 0
    doc = json.loads((out / 'energy.json').read_text())
    (w,) = [w for w in doc['warnings'] if 'infeasible schedule' in w]
    assert 'stance lasts 0.2 s < minimum 0.2214 s' in w


def _phase(t, gait, period, beta, step=0.1, legs=('L1', 'L2', 'L3', 'R1', 'R2', 'R3')):
    import numpy as np

    from hexapod_common.conversions import GaitPhaseSample
    from hexapod_gait.gait import make_gait

    g = make_gait(gait, duty_factor=beta, period_s=period, step_length_m=step,
                  step_height_m=0.04)
    return GaitPhaseSample(t_s=t, gait=gait, period_s=period, duty_factor=beta,
                           step_length_m=step, step_height_m=0.04, sweep_angle_rad=0.0,
                           leg_offset_rad=0.0, cycle_phase=(t / period) % 1.0,
                           leg_names=tuple(legs), phase_offsets=np.asarray(g.phase_offsets),
                           in_stance=np.zeros(len(legs), bool), supporting_legs=3)


def test_live_monitor_notes_an_infeasible_schedule_once() -> None:
    """The live energy_monitor computed an infeasible schedule's windows without a word (the
    offline command warned): the core now notes each infeasible schedule once, with the
    reasons the offline check gives, and keeps computing its windows."""
    from hexapod_energy.descriptors import DescriptorAccumulator
    from hexapod_gait.feasibility import ActuatorLimits

    acc = DescriptorAccumulator(mass_kg=2.183)
    for k in range(50):      # a feasible tripod: nothing
        acc.add_gait_phase(_phase(0.01 * k, 'tripod', 1.0, 0.5))
    assert acc.infeasible_ == [] and not any('infeasible' in n for n in acc.notes_)
    for k in range(50, 150):  # a wave at beta 0.1: limits and airborne phases, noted once
        acc.add_gait_phase(_phase(0.01 * k, 'wave', 1.0, 0.1))
    assert len(acc.infeasible_) == 1 and acc.infeasible_[0][0] == 0.5
    [note] = [n for n in acc.notes_ if 'infeasible' in n]
    assert 'stance lasts 0.1 s < minimum 0.15 s' in note and 'L(t) = 0' in note
    # a tripod at 0.9 m/s (period 0.2222 s) beyond AntBot's limits, within looser ones
    fast = DescriptorAccumulator(mass_kg=2.183)
    fast.add_gait_phase(_phase(0.0, 'tripod', 0.2222, 0.5))
    assert any('4.5 Hz > maximum 3 Hz' in n for n in fast.notes_)
    loose = DescriptorAccumulator(mass_kg=2.183, limits=ActuatorLimits(0.1, 0.1, 5.0))
    loose.add_gait_phase(_phase(0.0, 'tripod', 0.2222, 0.5))
    assert loose.infeasible_ == []
    # a standing schedule is not checked
    stand = DescriptorAccumulator(mass_kg=2.183)
    stand.add_gait_phase(dataclasses.replace(_phase(0.0, 'tripod', 1.0, 0.5), period_s=0.0))
    assert stand.infeasible_ == [] and stand.notes_ == []


@pytest.mark.parametrize('legs,mass', [(4, 1.851), (6, 2.183), (8, 2.515)])
def test_the_simulated_robot_mass_follows_the_leg_count(tmp_path, capsys, monkeypatch, legs,
                                                        mass) -> None:
    """A review: ``hexapod-sim robot --legs 4`` simulated the six-leg 2.183 kg robot while
    ``sim_robot -p leg_count:=4`` simulates AntBot's body with four legs, 1.851 kg."""
    from hexapod_bench_drivers import robot_sim

    seen = []

    class Spy(robot_sim.RobotSimulator):
        def __init__(self, config, **kw):
            seen.append(config.robot_mass_kg)
            super().__init__(config, **kw)

    monkeypatch.setattr(robot_sim, 'RobotSimulator', Spy)
    gait = ['--gait', 'alternating'] if legs != 6 else []
    rc, err = _sim(['--out', str(tmp_path / 'm'), '--legs', str(legs), *gait], capsys)
    assert rc == 0, err
    assert seen == [pytest.approx(mass, abs=1e-3)]
