"""Outside review K (reviewer-made bags, hidden effects) of ``hexapod-analyze residuals``:
the honesty of the selection, a cable after the monitor, leftovers under 1 % of the power,
the thermal slope's unit. Synthetic window tables (no ROS, no simulator), as the review's
six runs (tripod 0.4-1.0 s, tetrapod 0.75 s, wave 1.2 s) give them."""
from __future__ import annotations

import numpy as np
import pytest

from hexapod_energy import residuals as R
from hexapod_energy.effects_catalogue import (
    BasalPower, CarriedMass, KinematicError, LegAnomaly, PowerGain, SpeedFriction,
    ThermalDrift, WindowTable)
from hexapod_energy.unexplained import unexplained_residual

#: per run of the review's bags: step frequency [Hz], the bench's mass sensitivity [W/kg],
#: predicted power [W], speed [m/s], windows (the review's 1101)
RUNS = ((2.0, 8.29, 61.1, 0.4, 156), (1.43, 6.91, 44.4, 0.286, 100),
        (1.0, 5.90, 33.6, 0.2, 78), (1.33, 5.90, 41.7, 0.2, 312), (0.83, 4.74, 30.9, 0.1, 65),
        (2.5, 9.51, 77.8, 0.5, 390))


def _table(extra_w, *, noise=0.22, seed=0, runs=RUNS, stance=None, current_sq=None):
    """Windows of the review's runs, 40 s each, measured = predicted + ``extra_w(cols)`` +
    noise; ``cols``: dict of the per-window columns."""
    rng = np.random.default_rng(seed)
    run = np.concatenate([np.full(k, i) for i, (*_, k) in enumerate(runs)])
    t = np.concatenate([np.linspace(1.0, 40.0, k) for *_, k in runs])
    col = {name: np.concatenate([np.full(k, r[j]) for r in runs for k in [r[-1]]])
           for j, name in enumerate(('f', 'slope', 'pred', 'v'))}
    n = run.size
    col['i2'] = (col['pred'] / 12.0) ** 2 if current_sq is None else current_sq(col, rng)
    measured = col['pred'] + extra_w(col) + rng.normal(0.0, noise, n)
    return WindowTable(
        run=run, t_s=t, duration_s=np.full(n, 0.3), measured_w=measured,
        predicted_w=col['pred'], step_frequency_hz=col['f'], speed_mps=col['v'],
        current_sq_a2=col['i2'], temp_excess_k=np.full(n, np.nan),
        stance_fraction=np.full((n, 6), 0.5) if stance is None else stance(run, t, rng),
        leg_names=('L1', 'L2', 'L3', 'R1', 'R2', 'R3'),
        extra={'mass_slope_w_per_kg': col['slope'], 'robot_mass_kg': 2.183})


def _doc(table, catalogue):
    held = R.split_mask(table)
    sel = R.EffectSelection(catalogue=catalogue).fit(table, held)
    doc = R.energy_loop_document(table, sel, held)
    return sel, doc


def test_a_basal_power_and_kinematic_error_are_not_read_as_an_undeclared_payload():
    """Hidden basal 2 W + kinematic error 1.5 W/Hz: greedy selection took carried_mass first
    (an undeclared 0.52 kg, 24 % of the robot) and never reached the true pair, though its own
    table showed kinematic_error beside the basal power at a lower held-out error. The
    exchange step now swaps it in; the payload is not added."""
    table = _table(lambda c: 2.0 + 1.5 * c['f'])
    sel, doc = _doc(table, [BasalPower(), KinematicError(), CarriedMass()])
    assert sorted(doc['effects_added']) == ['basal_power', 'kinematic_error'], doc['summary']
    kin = next(a for a in doc['added_params'] if a['name'] == 'kinematic_error')
    assert kin['params']['w_per_hz'] == pytest.approx(1.5, rel=0.15)
    assert 'carried_mass' not in doc['effects_added']
    assert any(x['added'] == 'kinematic_error' for x in sel.exchanged_)


def test_an_effect_another_candidate_explains_as_well_is_undecided_in_the_json():
    """A constant 0.75 W with heavy noise (the review's Wi-Fi spikes): a leg anomaly was named
    on BIC, 'The model missed leg_anomaly', where a basal power in its place did as well on
    the held-out blocks. Now the JSON says the runs cannot tell them (``attribution``,
    ``identified`` false) and the summary does not say 'missed'."""
    def stance(run, t, rng):
        s = np.full((run.size, 6), 0.5)
        s[:, 2] = 0.5 + np.where((np.arange(run.size) % 2) == 0, 0.11, -0.11)
        return s

    # (seed 2: the leg anomaly is the one chosen, as in the review)
    table = _table(lambda c: 0.75 + np.zeros_like(c['f']), noise=1.3, seed=2, stance=stance)
    sel, doc = _doc(table, [BasalPower(), LegAnomaly(leg_index=2, leg='L3')])
    assert len(doc['effects_added']) == 1
    a = doc['added_params'][0]
    other = 'basal_power' if a['name'] == 'leg_anomaly' else 'leg_anomaly'
    assert other in [x['name'] for x in a.get('alternatives', [])]
    assert a['identified'] is False
    att = doc['attribution']
    assert att['status'] == 'undecided' and att['identified'] == []
    assert att['undecided'][0]['effect'] == a['name'] and other in att['undecided'][0]['or']
    assert 'The model missed' not in doc['summary'] and 'cannot tell it from' in \
        doc['summary']


def test_a_gain_that_explains_better_is_in_the_json_not_only_the_summary():
    """A DC-DC converter (8 % + 0.5 W): ``effects_added`` held kinematic_error, the summary
    alone said power_gain explained at least as well. ``attribution`` names it better."""
    table = _table(lambda c: 0.08 * c['pred'] + 0.5)
    sel, doc = _doc(table, [BasalPower(), KinematicError(), PowerGain()])
    att = doc['attribution']
    und = {u['effect']: u for u in att['undecided']}
    assert 'kinematic_error' in doc['effects_added']
    assert 'power_gain' in und['kinematic_error']['better']
    assert 'kinematic_error' not in att['identified']
    assert next(a for a in doc['added_params'] if a['name'] == 'kinematic_error')[
        'identified'] is False


def test_a_clean_attribution_is_identified():
    table = _table(lambda c: 3.0 + np.zeros_like(c['f']))
    _, doc = _doc(table, [BasalPower(), KinematicError(), PowerGain(), CarriedMass()])
    assert doc['effects_added'] == ['basal_power']
    assert doc['attribution']['status'] == 'identified'
    assert doc['attribution']['identified'] == ['basal_power']
    assert doc['added_params'][0]['identified'] is True


def test_a_cable_after_the_monitor_is_found_as_such():
    """0.15 ohm between the monitor and the robot (the paper's external supply, measured on
    its cable): P_in = Eq. 1 + R I^2. The catalogue had only a resistance before the monitor
    (a power decrease), and the loop named a speed friction of 9.23 N s/m and hot windings."""
    def current_sq(col, rng):
        # the current also follows what the speed does not (loads, gait): 8 % per window
        return (col['pred'] * (1.0 + 0.08 * rng.standard_normal(col['pred'].size)) / 12.0) ** 2

    from hexapod_energy.effects_catalogue import CableResistance

    table = _table(lambda c: 0.15 * c['i2'], current_sq=current_sq, seed=2)
    cat = R.residual_catalogue(table.leg_names)
    assert any(isinstance(e, CableResistance) for e in cat)
    _, doc = _doc(table, cat)
    assert doc['effects_added'] == ['cable_resistance'], doc['summary']
    p = doc['added_params'][0]['params']
    assert p['resistance_ohm'] == pytest.approx(0.15, rel=0.05)
    assert 'speed_friction' not in doc['effects_added']


def test_a_cable_the_runs_cannot_tell_from_a_friction_is_named_not_added():
    """The simulated robot's friction costs copper loss (current squared): there a 15 N s/m
    friction read as a 0.39 ohm cable. Where the cable does not beat the friction on the
    held-out blocks it is held back, named beside what is added."""
    from hexapod_energy.effects_catalogue import CableResistance

    table = _table(lambda c: 3.0 * 15.0 * c['v'] ** 2, seed=4)
    _, doc = _doc(table, [SpeedFriction(), CableResistance()])
    assert doc['effects_added'] == ['speed_friction']


def test_transfers_is_false_when_runs_left_out_hardly_gain():
    """Offsets between runs that no effect explains: a basal power fitted on the other runs
    moved a left-out run's error 1.10 -> 1.09 W and ``transfers`` read true."""
    rng = np.random.default_rng(7)
    runs, n_per = 5, 60
    run = np.repeat(np.arange(runs), n_per)
    # left-out runs: 0.989 -> 0.987 W with a basal power fitted on the others
    y = np.array([1.6, -0.4, 1.3, -0.2, 0.7])[run] + rng.normal(0.0, 0.05, run.size)
    n = run.size
    table = WindowTable(
        run=run, t_s=np.tile(np.arange(n_per) * 0.5, runs), duration_s=np.full(n, 0.5),
        measured_w=30.0 + y, predicted_w=np.full(n, 30.0),
        step_frequency_hz=np.full(n, 1.5), speed_mps=np.full(n, 0.2),
        current_sq_a2=np.ones(n), temp_excess_k=np.full(n, np.nan),
        stance_fraction=np.full((n, 6), 0.5), leg_names=tuple('ABCDEF'), extra={})
    lo = R.leave_one_run_out(table)
    assert lo is not None and not lo['transfers'], lo
    lo = R.leave_one_run_out(table, heldout=(1.0, 0.5))
    assert lo is not None
    assert lo['rmse_after'] <= lo['rmse_before']
    assert not lo['transfers'] and lo['verdict'] == 'little'
    doc = {'leave_one_run_out': lo, 'unit': 'W'}
    assert 'transfer' in R._loro_text(doc)


def test_a_step_under_one_percent_of_the_power_is_flagged_and_run_offsets_are_not():
    """A fan's +2 W step beside a basal power left 0.59 W of 59 W (2.6 noise floors): the
    1 %-of-mean rule kept it silent. A step within runs is now flagged under 1 %; offsets
    between runs under 1 % (clean simulated runs: 0.25-0.35 W, 10-14 noise floors) are not."""
    rng = np.random.default_rng(1)
    runs, n_per = 6, 80
    run = np.repeat(np.arange(runs), n_per)
    t = np.tile(np.arange(n_per) * 0.5, runs)
    step = np.where((run % 3 == 1) & (t > 15.0), 1.2, 0.0)
    r = step - np.mean(step) + rng.normal(0.0, 0.22, run.size)
    u = unexplained_residual(run, t, r, mean_power_w=62.0)
    assert u['structured_w'] < 0.01 * 62.0
    assert u['significant'] and u['pattern'] == 'step' and u.get('below_min_share')
    offs = np.array([-0.2, -0.28, 0.3, 0.25, -0.1, 0.05])[run] + rng.normal(0.0, 0.025,
                                                                             run.size)
    u = unexplained_residual(run, t, offs, mean_power_w=40.0)
    assert u['structured_w'] > 5 * u['noise_w'] and not u['significant']


def test_the_thermal_slope_says_per_servo_and_per_kelvin_of_the_mean():
    """``w_per_k`` is per servo-kelvin (the regressor sums 18 servos): 0.0068 W/K read as
    the robot's slope is 18 times off. The JSON gives the unit and the slope on the mean."""
    n = 90
    temp = np.linspace(30.0, 45.0, n)
    table = WindowTable(
        run=np.repeat(np.arange(3), 30), t_s=np.tile(np.arange(30) * 1.0, 3),
        duration_s=np.ones(n), measured_w=np.full(n, 40.0), predicted_w=np.full(n, 40.0),
        step_frequency_hz=np.full(n, 1.5), speed_mps=np.full(n, 0.2),
        current_sq_a2=np.ones(n), temp_excess_k=18 * (temp - 31.0),
        stance_fraction=np.full((n, 6), 0.5), leg_names=tuple('ABCDEF'),
        extra={'temp_sum_c': 18 * temp, 'servo_count': np.full(n, 18.0),
               'temp_coldest_c': 30.0, 'temp_bench_c': 31.0})
    p, e = ThermalDrift().params(np.array([0.0068, 0.0]), np.array([1e-4, 1e-3]), table)
    assert p['w_per_k_of_mean_temperature'] == pytest.approx(18 * 0.0068)
    assert 'each servo' in p['w_per_k_unit'] and p['servo_count'] == 18.0
    assert e['w_per_k_of_mean_temperature'] == pytest.approx(18e-4)


def test_hot_windings_are_suggested_only_when_a_residual_is_left():
    """'hot windings ... may account for part of the residual' ended every summary with warm
    servos, a clean run and a fully explained basal power too."""
    table = _table(lambda c: 3.0 + np.zeros_like(c['f']))
    _, doc = _doc(table, [BasalPower()])
    doc['servo_temperature'] = {'excess_over_bench_k': 14.5,
                                'per_run': [{'run': 'a', 'excess_k': 14.5}]}
    assert not doc['unexplained']['significant']
    text = R.summary_text(doc)
    assert "servos were 14.5 K warmer than the bench's" in text
    assert 'may account for part of the residual' not in text
    doc['unexplained'] = dict(doc['unexplained'], significant=True, pattern='other',
                              per_run=[], structured_w=1.0)
    assert 'may account for part of the residual' in R.summary_text(doc)
