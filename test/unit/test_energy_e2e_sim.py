"""Issue 6 acceptance on the simulators: bench plan -> surfaces -> predicted robot P_in, and the
paper's findings on the model fitted to simulated bench data.

Data: ``hexapod_bench_drivers`` bench plan of 5 loads x 8 frequencies (4 s walking per session)
and six tripod robot runs at 0.1 to 0.6 m/s, written to bags with the simulators' own writer and
read back through ``hexapod-analyze energy``.  Only the default effects are on (sensor noise), so
the robot has no effect the bench cannot see.  The bags are made once per module.

The simulated robot loads each stance tip with ``(m_c + m_leg) g`` (``robot_sim.tip_forces_n``)
and the simulated bench its tip with ``(m_leg + load) g``: the paper's bench load ``m_c``, no
``--load-offset``.
"""

from __future__ import annotations

import json
import math
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BENCH_LOADS_KG, BenchConfig, BenchPlan, BenchSimulator
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag
from hexapod_energy.cli import build_parser, run
from hexapod_energy.errors import InvalidInputError
from hexapod_energy.prediction import ANTBOT_ROBOT, OutputPowerModel, predict_power_in_w
from hexapod_energy.single_leg import SingleLegModel
from hexapod_energy.sweeps import (
    GAIT_TYPE_MIN_SPEED_MPS,
    STANDARD_SWEEPS,
    SweepSpec,
    run_standard_sweeps,
    sweep_curve,
)

FREQS_HZ = (0.0, 0.5, 0.8, 1.2, 1.6, 2.0, 2.5, 3.0)
SPEEDS_MPS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
LEG_KG = ANTBOT_ROBOT.leg_mass_kg


@pytest.fixture(scope='module')
def bags(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp('e2e')
    plan = BenchPlan(loads_kg=BENCH_LOADS_KG, frequencies_hz=FREQS_HZ, walk_s=4.0,
                     max_cool_s=5.0)
    write_trace(BenchSimulator(BenchConfig(), seed=3).run_plan(plan), root / 'bench')
    for i, v in enumerate(SPEEDS_MPS):
        write_trace(simulate_robot(6.0, RobotConfig(speed_mps=v), seed=10 + i),
                    root / f'robot_{v:.1f}')
    return root


@pytest.fixture(scope='module')
def bench_data(bags):
    """The bench bag read once (the schedule and the contact splits are taken from it)."""
    return read_bench_bag(bags / 'bench')


@pytest.fixture(scope='module')
def model(bench_data) -> SingleLegModel:
    samples, _ = bench_phase_samples(bench_data)
    return SingleLegModel().fit(samples)


def _analyze(bags: Path, out: Path, *extra: str) -> dict:
    robots = [str(bags / f'robot_{v:.1f}') for v in SPEEDS_MPS]
    args = build_parser().parse_args(['--bench', str(bags / 'bench'), '--robot', *robots,
                                      '--out', str(out), '--no-progress', *extra])
    run(args)
    return json.loads((out / 'energy.json').read_text())


@pytest.fixture(scope='module')
def model_out(bags, tmp_path_factory) -> tuple[dict, Path]:
    """``energy --power-out model`` on the bags, run once: its energy.json and output folder
    (the prediction test and the where-the-watts-go test read the same analysis). Read only."""
    out = tmp_path_factory.mktemp('model_out') / 'o'
    return _analyze(bags, out, '--power-out', 'model'), out


def test_predicted_robot_power_within_5_percent(model_out) -> None:
    doc, _ = model_out
    err = doc['prediction_error']
    fit = doc['bench']['fit']
    print(f"\nbench sessions {doc['bench']['diagnostics'][0]['sessions']}, surfaces "
          f"{fit['chosen']}, CV RMSE {fit['cv_rmse_w']}")
    for r in doc['robot_runs']:
        print(f"  v {r['speed']:.2f} m/s: measured {r['measured_power_in_w']:.2f} W, predicted "
              f"{r['predicted_power_in_w']:.2f} W "
              f"({100 * (r['predicted_power_in_w'] / r['measured_power_in_w'] - 1):+.1f} %), "
              f"P_out {r['power_out_w']:.3f} W ({r['power_out_source']}; from efforts "
              f"{r['power_out_effort_w']:.3f} W), eta {r['efficiency']:.4f}")
    print(f"  prediction: rmse {err['rmse_w']:.3f} W = {100 * err['relative_rmse']:.2f} % of "
          f"{err['mean_power_w']:.2f} W, bias {err['bias_w']:+.3f} W, worst "
          f"{100 * err['max_abs_relative']:.2f} %")
    assert err['runs'] == 6
    assert doc['bench']['diagnostics'][0]['sessions'] == 5 * 8
    speeds = [r['speed'] for r in doc['robot_runs']]
    np.testing.assert_allclose(speeds, SPEEDS_MPS, rtol=1e-6)
    assert err['relative_rmse'] < 0.05
    assert err['max_abs_relative'] < 0.06
    for r in doc['robot_runs']:
        # Eq. 6 positive joint power: the simulator's 0.5-6 % efficiency band (its issue)
        assert r['power_out_source'] == 'model'
        assert 0.003 < r['efficiency'] < 0.07
        # the simulated /joint_states effort is the AX load (PWM fraction x stall torque), not
        # a torque: effort x velocity overstates P_out (up to more than P_in at 0.6 m/s)
        assert r['power_out_effort_w'] > 10 * r['power_out_w']


def test_paper_load_convention_matches_simulated_robot(bags, tmp_path) -> None:
    """The simulated robot's stance tips carry M g / L like a real robot's (they carried only
    m_c g, 77 % of the weight, and needed --load-offset = m_leg): the paper's bench load m_c
    now predicts it with less bias than m_c - m_leg."""
    paper = _analyze(bags, tmp_path / 'paper')['prediction_error']
    net = _analyze(bags, tmp_path / 'net2', '--load-offset', f'{LEG_KG:.6f}')['prediction_error']
    print(f"\npaper convention bias {paper['bias_w']:+.3f} W ({100 * paper['relative_rmse']:.2f}"
          f" % rmse); m_c - m_leg bias {net['bias_w']:+.3f} W "
          f"({100 * net['relative_rmse']:.2f} % rmse)")
    assert abs(paper['bias_w']) < abs(net['bias_w'])


# ------------------------------------------------------------------------------- findings


@pytest.fixture(scope='module')
def curves(model):
    return run_standard_sweeps(model, OutputPowerModel(), n_speeds=30)


def _at(curve, speed_mps: float, payload_index: int = 0) -> dict[str, float]:
    return {k: float(np.interp(speed_mps, curve.speeds_mps, getattr(curve, k)[:, payload_index]))
            for k in ('power_in_w', 'power_out_w', 'cot_per_mass', 'efficiency')}


def test_finding_four_legs_lowest_cot_per_mass(curves) -> None:
    legs = {c.spec.leg_count: c for c in curves['leg_count']}
    best = {n: float(np.min(c.cot_per_mass[:, 0])) for n, c in legs.items()}
    print(f'\nmin CoT/M [J/(m kg)] by leg count: {best}')
    assert best[4] < best[6] < best[8]
    # at every speed and payload, not only at the optimum
    assert np.all(legs[4].cot_per_mass < legs[6].cot_per_mass)


def test_finding_best_point_at_maximum_speed(curves) -> None:
    for name, cs in curves.items():
        for c in cs:
            pts = c.optimal_points()
            print(f"\n{name} / {c.spec.label}: v_max {c.speeds_mps[-1]:.3f} m/s, min CoT/M "
                  f"{pts['min_cot_per_mass']['value']:.2f} at "
                  f"{pts['min_cot_per_mass']['speed_mps']:.3f}, max eta "
                  f"{pts['max_efficiency']['value']:.4f} at "
                  f"{pts['max_efficiency']['speed_mps']:.3f}, min eta {c.min_efficiency:.4f}",
                  end='')
            last = len(c.speeds_mps) - 1
            if abs(c.spec.step_length_m - 0.1) > 1e-9:
                # a step other than the bench's (100 mm) is read through its joint path: the
                # 140 mm curve's CoT/M flattens 0.6 % above its minimum at its top speed
                # (the model +0.7 % at 0.45 m/s, +5.2 % at 0.632; the simulated robot itself
                # still falls: 42.33 at 0.532, 41.54 at 0.632 m/s)
                assert np.all(c.cot_per_mass[last] <= 1.01 * c.cot_per_mass.min(axis=0)), \
                    c.spec.label
            else:
                assert np.all(np.argmin(c.cot_per_mass, axis=0) == last), c.spec.label
            assert np.all(np.argmax(c.efficiency, axis=0) == last), c.spec.label
            assert np.all(np.argmax(c.power_out_w, axis=0) == last), c.spec.label


@lru_cache(maxsize=None)
def _sim_loss_w(**kw) -> float:
    """Whole-cycle mean P_in - P_out of a simulated robot run (measured battery power, the
    servos' true positive output power), after one settling cycle."""
    cfg = RobotConfig(**kw)
    period = cfg.effective_period_s
    cycles = max(2, math.ceil(4.0 / period))
    tr = simulate_robot(period * (cycles + 1), cfg, seed=5)
    keep = tr.t_s > period + 1e-9
    p_in = -tr.battery_voltage_v[keep] * tr.battery_current_a[keep]
    p_out = np.clip(tr.true_mechanical_power_w[keep], 0.0, None).sum(axis=1)
    return float(np.mean(p_in - p_out))


@pytest.fixture(scope='module')
def findings(model) -> dict[str, dict[str, float]]:
    """The fitted model at the paper's two comparisons: tripod beta 0.5 / 0.7 at 0.26 m/s
    (no payload), tripod beta 0.5 / wave beta 0.83 at 0.1 m/s with 0.5 kg."""
    opm = OutputPowerModel()
    pay = (0.0, 0.5)
    return {
        'b5': _at(sweep_curve(SweepSpec('b5', 'tripod', 6, 0.5), model, opm), 0.26),
        'b7': _at(sweep_curve(SweepSpec('b7', 'tripod', 6, 0.7), model, opm), 0.26),
        'tri': _at(sweep_curve(SweepSpec('t', 'tripod', 6, 0.5), model, opm, payloads_kg=pay),
                   0.1, 1),
        'wave': _at(sweep_curve(SweepSpec('w', 'wave', 6, 0.83), model, opm, payloads_kg=pay),
                    0.1, 1),
    }


def test_duty_factor_and_wave_findings_follow_the_simulator(findings) -> None:
    """beta 0.7 vs 0.5 at 0.26 m/s and wave vs tripod at 0.1 m/s with 0.5 kg: the fitted model
    and the simulated robot agree on the direction of the power-loss change."""
    b5, b7, tri, wave = (findings[k] for k in ('b5', 'b7', 'tri', 'wave'))
    sim_b5 = _sim_loss_w(speed_mps=0.26, duty_factor=0.5)
    sim_b7 = _sim_loss_w(speed_mps=0.26, duty_factor=0.7)
    sim_tri = _sim_loss_w(speed_mps=0.1, payload_kg=0.5)
    sim_wave = _sim_loss_w(speed_mps=0.1, payload_kg=0.5, gait='wave', duty_factor=0.83)
    mass = ANTBOT_ROBOT.mass_kg
    loss = lambda d: d['power_in_w'] - d['power_out_w']  # noqa: E731
    print(f"\nbeta 0.7 vs 0.5 at 0.26 m/s: P_loss model {loss(b7):.2f} vs {loss(b5):.2f} W "
          f"({100 * (loss(b7) / loss(b5) - 1):+.1f} %), simulator {sim_b7:.2f} vs {sim_b5:.2f} W "
          f"({100 * (sim_b7 / sim_b5 - 1):+.1f} %); P_out model {b7['power_out_w']:.3f} vs "
          f"{b5['power_out_w']:.3f} W; CoT/M {b7['cot_per_mass']:.1f} vs "
          f"{b5['cot_per_mass']:.1f} (sim {sim_b7 / (mass * 0.26):.1f} vs "
          f"{sim_b5 / (mass * 0.26):.1f})")
    print(f"wave 0.83 vs tripod at 0.1 m/s, 0.5 kg: P_loss model {loss(wave):.2f} vs "
          f"{loss(tri):.2f} W ({100 * (loss(wave) / loss(tri) - 1):+.1f} %), simulator "
          f"{sim_wave:.2f} vs {sim_tri:.2f} W ({100 * (sim_wave / sim_tri - 1):+.1f} %)")
    assert np.sign(loss(b7) - loss(b5)) == np.sign(sim_b7 - sim_b5)
    assert np.sign(loss(wave) - loss(tri)) == np.sign(sim_wave - sim_tri)
    # output power rises with the duty factor, as in the paper (+192 % there)
    assert b7['power_out_w'] > 2 * b5['power_out_w']
    assert wave['power_out_w'] > tri['power_out_w']


@pytest.mark.parametrize('payload_kg', [0.14, 0.5])
def test_paper_direction_wave_beats_tripod_at_low_speed_under_load(model, payload_kg) -> None:
    """Brodoline et al. Fig. 3C: with a load, the wave gait (beta 0.83) loses less than the
    tripod at low speed (up to -8 % CoT/M below 0.13 m/s there, 140 g). On the simulator the
    saving lies at the slowest speeds: the fitted model and the simulated robot both give it
    at 0.02-0.04 m/s, and both reverse it by 0.1 m/s (swings 1.4 to 5 times as often)."""
    opm = OutputPowerModel()
    pay = (0.0, payload_kg)
    tri, wave = (sweep_curve(SweepSpec(g, g, 6, b), model, opm, payloads_kg=pay,
                             min_speed_mps=0.02) for g, b in (('tripod', 0.5), ('wave', 0.83)))
    mass = ANTBOT_ROBOT.mass_kg + payload_kg
    print()
    for v in (0.02, 0.04, 0.1):
        m_t, m_w = (_at(c, v, 1)['cot_per_mass'] for c in (tri, wave))
        s_t = _sim_loss_w(speed_mps=v, payload_kg=payload_kg)
        s_w = _sim_loss_w(speed_mps=v, payload_kg=payload_kg, gait='wave', duty_factor=0.83)
        print(f'{payload_kg} kg, {v} m/s: wave vs tripod CoT/M model {m_w:.1f} vs {m_t:.1f} '
              f'({100 * (m_w / m_t - 1):+.1f} %), simulated robot {s_w / (mass * v):.1f} vs '
              f'{s_t / (mass * v):.1f} ({100 * (s_w / s_t - 1):+.1f} %)')
        if v <= 0.04:   # model -14 / -9 %, robot -5 / -2 % (0.14 kg), -12 / -9 % (0.5 kg)
            assert m_w < m_t and s_w < s_t
        else:           # the swings' cost: model +27 %, robot +6 to +12 %
            assert m_w > m_t and s_w > s_t
    # the standard gait-type sweep (Fig. 3C) starts low enough to show it
    assert {c.min_speed_mps for c in STANDARD_SWEEPS['gait_type']} == {GAIT_TYPE_MIN_SPEED_MPS}
    assert GAIT_TYPE_MIN_SPEED_MPS <= 0.02


def test_gait_type_comparison_locates_the_wave_saving(curves, model, tmp_path) -> None:
    """The standard gait-type curves compared (energy.json gait_type_comparison): the wave is
    cheaper up to 0.04-0.09 m/s at every payload, by about 20 % at best, and dearer at its top
    speed; in the fitted model that saving lies where the phases outlast the bench's
    slowest walking session (extrapolated between it and the standing session)."""
    from hexapod_energy.plots import comparison_plot
    from hexapod_energy.sweeps import compare_curves

    tri, wave = curves['gait_type'][:2]
    cmp = compare_curves(tri, wave)
    print(f"\nwave cheaper up to {cmp['below_one_until_mps']} m/s; best ratio "
          f"{cmp['best_ratio']} at {cmp['best_speed_mps']} m/s")
    for j in range(len(cmp['payloads_kg'])):
        assert 0.04 < cmp['below_one_until_mps'][j] < 0.09
        assert cmp['best_ratio'][j] < 0.9
        assert cmp['ratio'][-1, j] > 1.0
        best = int(np.argmin(cmp['ratio'][:, j]))
        assert cmp['outside_bench'][best, j]
    paths = comparison_plot(cmp, tmp_path / 'cmp')
    assert paths[0].stat().st_size > 10_000
    with pytest.raises(InvalidInputError, match='payloads'):
        compare_curves(tri, sweep_curve(SweepSpec('w', 'wave', 6, 0.83), model,
                                        OutputPowerModel(), payloads_kg=(0.0,)))


@pytest.mark.xfail(strict=True, reason=(
    'simulator physics, measured with bench/bench_sim_breakdown.py --budget/--candidates: at '
    'one speed and step length the stance lasts L/v whatever the duty factor, so beta 0.7 can '
    'only save the holding copper of sharing the weight over 4.2 instead of 3 legs (at most '
    '1.7 W of 4.3 W at 0.26 m/s) while its swings come 1.4 times as often and are shorter: '
    '2.29 J per 0.165 s swing of one leg against 1.84 J per 0.385 s swing, +10.6 W for the '
    'robot (the 0.165 s swing of the gait spline asks 13.4 rad/s, beyond the 10.0 rad/s '
    'no-load speed; the spline reaches that speed at a 0.22 s swing). A load-proportional '
    'gear friction cannot move cost into the loaded stance: the stance joints transmit '
    'sum |tau w| = 0.13 W (0.30 W at 0.6 m/s). Datasheet-honest no-load friction (0.2 A), a '
    'coreless rotor and dithered friction give beta 0.7 still +18 % (break-even needs 5.1 '
    'times the stance copper), and break the 0.6 m/s efficiency, CoT/M and thermal bands. '
    'With the calibrated servo the simulated robot loses +31 %, the fitted model +41 %'))
def test_paper_direction_beta(findings) -> None:
    b5, b7 = findings['b5'], findings['b7']
    # the paper: about -10 % energy loss (beta 0.7 against 0.5 at 0.26 m/s)
    assert b7['cot_per_mass'] < b5['cot_per_mass']
    assert _sim_loss_w(speed_mps=0.26, duty_factor=0.7) < _sim_loss_w(speed_mps=0.26,
                                                                      duty_factor=0.5)


def test_where_the_watts_go(model_out) -> None:
    """Each robot run's Eq. 1 power split by phase and into holding (the bench's basal power
    at the loads the legs carry) and motion; the parts add up to the prediction, the rest is
    what the bench model does not explain; drawn as stacked bars."""
    doc, out = model_out
    basal = doc['bench']['fit']['basal_power_w']
    assert basal, 'the plan has 0 Hz sessions'
    print()
    for r in doc['robot_runs']:
        b = r['power_breakdown_w']
        print(f"  v {r['speed']:.2f} m/s: P_in {b['measured_w']:.2f} W = holding "
              f"{b['holding_w']:.2f} ({100 * b['holding_share']:.0f} %) + stance motion "
              f"{b['stance_motion_w']:.2f} + swing motion {b['swing_motion_w']:.2f} + "
              f"unmodelled {b['unmodelled_w']:+.2f}")
        assert b['stance_w'] + b['swing_w'] == pytest.approx(r['predicted_power_in_w'])
        assert b['holding_w'] + b['stance_motion_w'] + b['swing_motion_w'] == \
            pytest.approx(b['predicted_w'])
        assert b['predicted_w'] + b['unmodelled_w'] == pytest.approx(r['measured_power_in_w'])
        # six legs at the bench's basal power: between the unloaded and the heaviest session
        lo, hi = min(basal.values()), max(basal.values())
        assert 6 * lo - 1e-9 <= b['holding_w'] <= 6 * hi + 1e-9
    shares = [r['power_breakdown_w']['holding_share'] for r in doc['robot_runs']]
    motion = [r['power_breakdown_w']['swing_motion_w'] for r in doc['robot_runs']]
    # holding weighs most at low speed; swinging faster costs more
    assert shares[0] == max(shares) and shares[-1] == min(shares)
    assert np.all(np.diff(motion) > 0)
    assert 'where_the_watts_go.png' in doc['plots']
    assert (out / 'where_the_watts_go.png').stat().st_size > 10_000


def test_schedule_split_transfers_to_other_gaits(bench_data, model, tmp_path) -> None:
    """Eq. 1 composes the bench's phase powers on the commanded timeline: labelled by the bench
    leg's commanded stance (the default with /gait/phase) the prediction of gaits far from the
    bench's beta 0.5 holds; labelled by the sensed contact (the paper's split: the contact
    outlasts the commanded stance, so part of the swing's cost lands in the stance surface)
    it over-predicts them."""
    from hexapod_energy.bag_io import read_robot_bag
    from hexapod_energy.descriptors import gait_from_sample

    contact = SingleLegModel().fit(bench_phase_samples(bench_data, phase_split='contact')[0])
    cases = [('wave', 0.83, 0.1), ('tetrapod', 0.67, 0.15)]
    errors = {}
    for gait, beta, speed in cases:
        path = tmp_path / gait
        write_trace(simulate_robot(6.0, RobotConfig(gait=gait, duty_factor=beta,
                                                    speed_mps=speed), seed=21), path)
        run = read_robot_bag(path, mass_kg=ANTBOT_ROBOT.mass_kg)
        g = gait_from_sample(run.gait)
        kw = dict(total_mass_kg=ANTBOT_ROBOT.mass_kg, leg_mass_kg=LEG_KG)
        errors[gait] = [predict_power_in_w(m, g, **kw) / run.power_in_w - 1.0
                        for m in (model, contact)]
        print(f'\n{gait} beta {beta} at {speed} m/s: measured {run.power_in_w:.2f} W; '
              f'prediction error schedule split {100 * errors[gait][0]:+.1f} %, contact split '
              f'{100 * errors[gait][1]:+.1f} %')
    for sched, cont in errors.values():
        assert abs(sched) < 0.12 and abs(sched) < 0.6 * abs(cont)   # +9.7 % and +5.8 %


@lru_cache(maxsize=None)
def _sim_power_in_w(**kw) -> float:
    """Whole-cycle mean battery power of a simulated robot run after one settling cycle."""
    cfg = RobotConfig(**kw)
    period = cfg.effective_period_s
    cycles = max(2, math.ceil(4.0 / period))
    tr = simulate_robot(period * (cycles + 1), cfg, seed=5)
    keep = tr.t_s > period + 1e-9
    return float(np.mean(-tr.battery_voltage_v[keep] * tr.battery_current_a[keep]))


@pytest.mark.parametrize('length,height', [(0.07, 0.04), (0.14, 0.04), (0.10, 0.02),
                                           (0.10, 0.06)])
def test_other_step_geometries_are_mapped_onto_the_bench_path(model, length, height) -> None:
    """An outside review: Eq. 1 read the surfaces at the phase durations alone, so 70 and
    140 mm steps and 20 and 60 mm lifts (the bench walked 100 and 40 mm) were predicted
    +14 %, -16 %, +14 %, -17 % at 0.3 m/s, with no warning; the step-length sweep and the
    recommendation followed. The phases are now read at the duration that covers the bench's
    joint path at the run's joint speeds."""
    from hexapod_gait.gait import make_gait

    assert model.bench_step_ == pytest.approx((0.1, 0.04))
    v = 0.3
    gait = make_gait('tripod', duty_factor=0.5, period_s=length / (0.5 * v),
                     step_length_m=length, step_height_m=height)
    measured = _sim_power_in_w(speed_mps=v, step_length_m=length, step_height_m=height)
    got = predict_power_in_w(model, gait, total_mass_kg=ANTBOT_ROBOT.mass_kg,
                             leg_mass_kg=LEG_KG)
    assert got == pytest.approx(measured, rel=0.07)
    blind = predict_power_in_w(type('Blind', (), {'p_stance_w': model.p_stance_w,
                                                  'p_swing_w': model.p_swing_w})(),
                               gait, total_mass_kg=ANTBOT_ROBOT.mass_kg, leg_mass_kg=LEG_KG)
    assert abs(blind / measured - 1) > 0.1                      # the durations alone


def test_an_extrapolation_note_gives_the_runs_own_durations(bags, tmp_path) -> None:
    """The note quoted the bench step's equivalent durations only ("stance 1.8 s" for a
    1.4 s stance on an 80 mm step: an outside review); it now says so and gives the run's."""
    write_trace(simulate_robot(9.0, RobotConfig(speed_mps=0.05, step_length_m=0.07), seed=5),
                tmp_path / 'slow70')
    args = build_parser().parse_args(['--bench', str(bags / 'bench'), '--robot',
                                      str(tmp_path / 'slow70'), '--out', str(tmp_path / 'o'),
                                      '--no-progress'])
    run(args)
    doc = json.loads((tmp_path / 'o' / 'energy.json').read_text())
    [note] = [w for w in doc['warnings'] if 'extrapolates the bench surfaces' in w]
    assert "durations at the bench step's equivalent" in note
    assert "this run's stance 1.4 s and swing 1.4 s on its 70 mm step" in note
