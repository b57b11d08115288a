"""Energy residual loop (issue 8) on simulated bench and robot bags, the analysis not told the
effects: each effect is selected first, held-out RMSE at least halves, its parameter is within
20 %; two effects are both found; clean data adds nothing; bad input names what is missing."""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path

import numpy as np
import pytest

from hexapod_bench_drivers.effects import parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy import residuals as R
from hexapod_energy.errors import BagContentError
from hexapod_energy.prediction import RobotSpec
from hexapod_energy.residuals_cli import add_cli

PERIODS_S = (1.0, 0.7, 0.5)       # three tripod runs: 1, 1.43, 2 Hz
RUN_S = 10.0
#: the simulated robot's stance tips carry (M - m_leg L) g / L, the bench's (m_leg + load) g
LEG_KG = RobotSpec().leg_mass_kg


@pytest.fixture(scope='module')
def bench(resid_bench):
    """One clean bench bag and its single-leg fit, shared by every test (and by the other
    residual test files: ``resid_bench`` in conftest.py)."""
    return resid_bench


def robot_bags(root: Path, effects: list[str], *, temps=(26.0, 26.0, 26.0),
               run_s: float = RUN_S, payload_kg: float = 0.0) -> list[Path]:
    root.mkdir(parents=True, exist_ok=True)
    out = []
    for i, period in enumerate(PERIODS_S):
        path = root / f'run{i}'
        cfg = RobotConfig(period_s=period, initial_temperature_c=temps[i],
                          payload_kg=payload_kg)
        write_trace(simulate_robot(run_s, cfg, effects=parse_effects(effects), seed=10 + i),
                    path)
        out.append(path)
    return out


def loop(bench, bags) -> dict:
    runs = [R.read_residual_run(p) for p in bags]
    return R.energy_loop_from_runs(bench['model'], runs, None, temp_ref_c=bench['temp_ref_c'])


def added(doc: dict, name: str) -> dict:
    return next(a for a in doc['added_params'] if a['name'] == name)


@pytest.fixture(scope='module')
def clean_bags(tmp_path_factory):
    return robot_bags(tmp_path_factory.mktemp('clean'), [])


@pytest.fixture(scope='module')
def clean_read(clean_bags):
    """The clean bags read once; :func:`clean_runs` hands out copies (the loop sets each
    run's prediction, and tests change their currents)."""
    return [R.read_residual_run(p) for p in clean_bags]


@pytest.fixture
def clean_runs(clean_read):
    """A fresh copy of the clean runs, as ``R.read_residual_run`` of each clean bag gives."""
    return copy.deepcopy(clean_read)


@pytest.fixture(scope='module')
def clean(bench, clean_read):
    return R.energy_loop_from_runs(bench['model'], copy.deepcopy(clean_read), None,
                                   temp_ref_c=bench['temp_ref_c'])


@pytest.fixture(scope='module')
def effect_bags(tmp_path_factory):
    """Robot bags with effects, simulated once per (effects, temperatures): an effect's own
    case, the CLI test and the bags without /gait/phase read the same runs."""
    made: dict[tuple, list[Path]] = {}

    def get(effects: list[str], temps=(26.0, 26.0, 26.0)) -> list[Path]:
        key = (tuple(effects), tuple(temps))
        if key not in made:
            made[key] = robot_bags(tmp_path_factory.mktemp('effect'), effects, temps=temps)
        return made[key]
    return get


@pytest.fixture(scope='module')
def effect_loop(bench, effect_bags):
    """The loop on :func:`effect_bags`' runs, once per (effects, temperatures). Read only."""
    made: dict[tuple, dict] = {}

    def get(effects: list[str], temps=(26.0, 26.0, 26.0)) -> dict:
        key = (tuple(effects), tuple(temps))
        if key not in made:
            made[key] = loop(bench, effect_bags(effects, temps))
        return made[key]
    return get


def test_clean_runs_leave_no_unexplained_residual(clean):
    u = clean['unexplained']
    print(f"\nclean: final {u['rmse_w']:.3f} W, noise {u['noise_w']:.3f} W, isolated "
          f"{u['isolated']}")
    assert not u['significant'] and 'no effect of the catalogue' not in clean['summary']
    assert u['noise_w'] < 0.1 and u['rmse_w'] < 0.01 * np.mean(
        [r['measured_w'] for r in clean['per_run']])


def test_an_accessory_switched_on_mid_run_is_reported_unexplained(bench, clean_runs, tmp_path):
    """An effect outside the catalogue: +3 W (a camera or a computer switched on) from the
    middle of each run. The loop fits what it can (here an undeclared mass and thermal drift)
    and said nothing of the 1.4 W it left; now the leftover is named, with its shape: a step
    of about +3 W half-way through the runs."""
    runs = clean_runs
    for r in runs:
        extra_w = np.where(r.t_s - r.t_s[0] > 0.5 * (r.t_s[-1] - r.t_s[0]), 3.0, 0.0)
        r.current_a = r.current_a + extra_w / r.voltage_v
        r.power_w = r.voltage_v * r.current_a
    doc = R.energy_loop_from_runs(bench['model'], runs, tmp_path, temp_ref_c=bench['temp_ref_c'])
    u = doc['unexplained']
    print(f"\n{doc['summary']}")
    assert 'residual_unexplained.png' in doc['plots']
    assert (tmp_path / 'residual_unexplained.png').stat().st_size > 10_000
    assert json.loads((tmp_path / 'residuals.json').read_text())['unexplained']['pattern'] == \
        'step'
    assert u['significant'] and u['pattern'] == 'step'
    assert u['structured_w'] > 10 * u['noise_w']
    assert 'steps within runs' in doc['summary']
    run_s = [r.t_s[-1] - r.t_s[0] for r in runs]
    for row, dur in zip(u['per_run'], run_s):
        # the step's place within half a second of the switch
        assert abs(row['at_s'] - 0.5 * dur) < 0.5, row
    assert np.median([row['step_w'] for row in u['per_run']]) > 2.0


CASES = [
    # effect on the robot, name, parameter, true value, initial servo temperatures
    (['basal_power=3'], 'basal_power', 'power_w', 3.0, (26.0, 26.0, 26.0)),
    (['kinematic_error=3'], 'kinematic_error', 'w_per_hz', 3.0, (26.0, 26.0, 26.0)),
    (['supply_resistance=0.3'], 'supply_resistance', 'resistance_ohm', 0.3, (26.0, 26.0, 26.0)),
    (['speed_friction=15'], 'speed_friction', 'c_n_s_per_m', 15.0, (26.0, 26.0, 26.0)),
    (['leg_anomaly=L2:2'], 'leg_anomaly', 'power_w', 2.0, (26.0, 26.0, 26.0)),
    (['thermal_drift=0.05'], 'thermal_drift', 'w_per_k', 0.05, (50.0, 26.0, 38.0)),
]


@pytest.mark.parametrize('effects,name,param,true,temps', CASES,
                         ids=[c[1] for c in CASES])
def test_each_effect_is_found_first_and_recovered(effect_loop, effects, name, param, true,
                                                   temps):
    doc = effect_loop(effects, temps)
    assert doc['effects_added'][0] == name, doc['summary']
    h = doc['heldout']
    assert h['rmse_after'] <= 0.5 * h['rmse_before']
    got = added(doc, name)['params'][param]
    np.testing.assert_allclose(got, true, rtol=0.2)
    if name == 'leg_anomaly':
        p = added(doc, name)['params']
        assert {p['leg'], *p['same_stance_as']} == {'L2', 'R1', 'R3'}   # L2's tripod


def test_two_effects_are_both_found(bench, tmp_path):
    """Both are added first. The simulated tracking error also overshoots the joints' motion
    (a cost growing about as f^2, 0.55 W at 2 Hz for 3 W/Hz): the f^2-shaped speed_friction
    term may follow with a small coefficient (3 N s/m here, against 15 in its own case)."""
    doc = loop(bench, robot_bags(tmp_path, ['kinematic_error=3', 'leg_anomaly=L2:2']))
    assert set(doc['effects_added'][:2]) == {'kinematic_error', 'leg_anomaly'}
    assert set(doc['effects_added'][2:]) <= {'speed_friction'}
    np.testing.assert_allclose(added(doc, 'kinematic_error')['params']['w_per_hz'], 3.0,
                               rtol=0.2)
    np.testing.assert_allclose(added(doc, 'leg_anomaly')['params']['power_w'], 2.0, rtol=0.2)


def test_undeclared_payload_is_named_with_its_mass(bench, tmp_path):
    """0.5 kg on the robot that the analysis was not told of. On tripod runs alone its extra
    power (about 2.1 W at every speed, the stance tips carrying the leg's weight too) is nearly
    constant, like a basal power: the loop may pick either, but it must name carried_mass with
    the mass, and say that these runs cannot tell the two apart.

    The mass is the extra power over the bench model's mass sensitivity at the robot's stance
    loads (0.73-0.9 kg per tip with the leg, beyond the bench's 0.6 kg load): 2.7-2.8 W/kg with
    the commanded-schedule split (the default), 0.82 kg for 0.5. The simulated robot's load
    cost is steeper there than the bench surfaces extrapolate (copper loss grows with the
    square of the holding torque). With the contact split the clean runs are over-predicted by
    0.87 W (contact outlasts the commanded stance and carries swing-end energy into P_stance),
    the payload then reads as basal_power 1.45 W alone; not asserted."""
    doc = loop(bench, robot_bags(tmp_path, [], payload_kg=0.5))
    first = doc['added_params'][0]
    named = [first] + first.get('alternatives', [])
    mass = next(a for a in named if a['name'] == 'carried_mass')
    assert 0.5 < mass['params']['mass_kg'] < 0.95, mass
    assert 'carried_mass (mass_kg = ' in doc['summary']
    if first['name'] != 'carried_mass':
        assert 'cannot tell it from' in doc['summary']
    # the bags declare it in their metadata (energy reads it): said per run, not hidden (an
    # outside review: the summary said that no run declares a payload)
    assert set(doc['bag_payloads_kg'].values()) == {0.5} and len(doc['bag_payloads_kg']) == 3
    for entry in doc['per_run']:
        assert entry['bag_payload_kg'] == 0.5
        assert any('its bag declares a payload of 0.5 kg' in n and '--robot-payload 0.5' in n
                   for n in entry['notes'])
    assert 'no run declares a payload' not in doc['summary']


def test_carried_mass_is_recovered_where_the_gait_tells_it_apart():
    """Synthetic windows: the residual is 0.4 kg times the bench's mass sensitivity, which
    varies across windows unlike step frequency (duty factors differ); carried_mass is added
    alone, at 0.4 kg, with no alternative named."""
    from hexapod_energy.effects_catalogue import WindowTable

    rng = np.random.default_rng(3)
    n = 120
    freq = np.repeat([1.0, 1.4, 2.0, 1.0, 1.4, 2.0], n // 6)
    slope = np.repeat([1.7, 1.8, 2.1, 1.1, 1.2, 1.4], n // 6)   # W/kg; beta 0.5 then 0.7
    measured = 30.0 + 0.4 * slope + rng.normal(0.0, 0.02, n)
    table = WindowTable(
        run=np.repeat(np.arange(6), n // 6), t_s=np.tile(np.arange(n // 6) * 0.5, 6),
        duration_s=np.full(n, 0.5), measured_w=measured, predicted_w=np.full(n, 30.0),
        step_frequency_hz=freq, speed_mps=0.1 * freq, current_sq_a2=np.full(n, 6.0),
        temp_excess_k=np.full(n, np.nan), stance_fraction=np.full((n, 6), 0.5),
        leg_names=('L1', 'L2', 'L3', 'R1', 'R2', 'R3'),
        extra={'mass_slope_w_per_kg': slope})
    held = np.tile(np.arange(n // 6) % 3 == 2, 6)
    sel = R.EffectSelection().fit(table, held)
    assert [e.name for e in sel.selected_] == ['carried_mass']
    np.testing.assert_allclose(sel.final_params_[0][0]['mass_kg'], 0.4, rtol=0.05)
    assert sel.alternatives_ == {}


def test_an_effect_the_selected_ones_already_span_is_not_added():
    """A residual of about 3 W whose small variation across runs follows the mass
    sensitivity: basal_power is added; carried_mass, whose regressor over tripod runs is nearly
    constant (1.7-2.0 W/kg), would split the 3 W by that small variation (without the rule:
    2.4 W and 0.35 kg), so it is not added and its record names basal_power."""
    from hexapod_energy.effects_catalogue import BasalPower, CarriedMass, WindowTable

    n = 90
    freq = np.repeat([1.0, 1.43, 2.0], n // 3)
    slope = np.repeat([1.67, 1.68, 2.03], n // 3)
    rng = np.random.default_rng(1)
    # 3 W in all, a small part of it shaped like the mass sensitivity
    measured = 30.0 + 2.4 + 0.35 * slope + rng.normal(0.0, 0.01, n)
    table = WindowTable(
        run=np.repeat(np.arange(3), n // 3), t_s=np.tile(np.arange(n // 3) * 0.5, 3),
        duration_s=np.full(n, 0.5), measured_w=measured, predicted_w=np.full(n, 30.0),
        step_frequency_hz=freq, speed_mps=0.1 * freq, current_sq_a2=np.full(n, 6.0),
        temp_excess_k=np.full(n, np.nan), stance_fraction=np.full((n, 6), 0.5),
        leg_names=('L1', 'L2', 'L3', 'R1', 'R2', 'R3'),
        extra={'mass_slope_w_per_kg': slope})
    held = np.tile(np.arange(n // 3) % 3 == 2, 3)
    sel = R.EffectSelection(catalogue=[BasalPower(), CarriedMass()]).fit(table, held)
    assert [e.name for e in sel.selected_] == ['basal_power']
    [mass] = [c for c in sel.candidates_ if c['name'] == 'carried_mass']
    assert mass['indistinguishable_from'] == ['basal_power']
    np.testing.assert_allclose(sel.final_params_[0][0]['power_w'], 3.0, atol=0.2)


def test_uniformly_warm_servos_are_named_beside_what_is_added(bench, tmp_path):
    """Clean runs whose servos all sit at 45 degC (a robot that walked before the recording)
    against a 27 degC bench: the temperature does not vary, so hot windings cannot be told
    from a gain or a kinematic error; they used to be 'not applicable' and the summary never
    said the servos were 18 K warmer (outside review). Now hot_windings is named as an
    alternative at the copper-and-magnet fraction, the summary gives the temperatures, and no
    effect is both added and an alternative."""
    doc = loop(bench, robot_bags(tmp_path / 'warm45', [], temps=(45.0, 45.0, 45.0)))
    assert 'hot_windings' not in doc['effects_added'] and doc['effects_added']
    alts = [x for a in doc['added_params'] for x in a.get('alternatives', [])]
    [hot] = [x for x in alts if x['name'] == 'hot_windings']
    assert 0.003 <= hot['params']['per_k'] <= 0.0055
    assert all(x['name'] not in doc['effects_added'] for x in alts)
    assert doc['servo_temperature']['excess_over_bench_k'] == pytest.approx(18.0, abs=0.5)
    assert "servos were 18.0 K warmer than the bench's" in doc['summary']


def test_an_effect_the_later_ones_explain_is_dropped():
    """Backward step: a kinematic error chosen first on a warming robot's runs stayed in the
    report at 0 +- 0.018 W/Hz once a thermal drift and a basal power stood beside it. Here the
    residual is a basal power and a thermal drift; of the three selected effects the kinematic
    error is dropped, and the other two are kept (each still lowers the held-out error)."""
    from hexapod_energy.effects_catalogue import (
        BasalPower, KinematicError, ThermalDrift, WindowTable)

    rng = np.random.default_rng(5)
    n, k = 240, 80
    freq = np.repeat([1.0, 1.43, 2.0], k)
    temp = np.concatenate([18.0 * (0.5 * f + 0.02 * np.arange(k)) for f in (1.0, 1.43, 2.0)])
    measured = 30.0 + 0.9 + 0.01 * temp + rng.normal(0.0, 0.03, n)
    table = WindowTable(
        run=np.repeat(np.arange(3), k), t_s=np.tile(np.arange(k) * 0.5, 3),
        duration_s=np.full(n, 0.5), measured_w=measured, predicted_w=np.full(n, 30.0),
        step_frequency_hz=freq, speed_mps=0.1 * freq, current_sq_a2=np.full(n, 6.0),
        temp_excess_k=temp, stance_fraction=np.full((n, 6), 0.5),
        leg_names=('L1', 'L2', 'L3', 'R1', 'R2', 'R3'), extra={})
    held = np.tile(np.arange(k) % 3 == 2, 3)
    train = ~held
    kin, basal, thermal = KinematicError(), BasalPower(), ThermalDrift()
    sel = R.EffectSelection()
    assert sel._prune([kin, basal, thermal], table, train, held) == [kin]
    assert sel._prune([basal, thermal], table, train, held) == []
    # the kinematic error alone would be fitted at a positive value: it is the others that
    # explain it away
    coef, *_ = sel._fit([kin], table, train)
    assert coef[0] > 0.3


def test_clean_data_adds_nothing(clean):
    assert clean['effects_added'] == []
    h = clean['heldout']
    assert abs(h['rmse_after'] - h['rmse_before']) <= 0.05 * h['rmse_before']
    assert 'none was added' in clean['summary']
    # with the matching tip-load convention and cross-validated spans the bench-derived
    # prediction is unbiased to a fraction of a watt (27-43 W measured)
    assert abs(clean['baseline']['bias']) < 0.3


def test_warm_servos_are_hot_windings_not_a_friction(bench, clean_read, tmp_path):
    """Clean runs whose servos are warmer than the bench's (50, 26 and 38 degC against 27):
    the simulator's copper resistance and magnet flux follow the temperature, so every watt
    costs more. Before ``hot_windings`` the loop named a thermal drift of 0.0063 W/K with a
    speed friction of 1.45 N s/m beside it (there is no friction); now the warm windings alone,
    at the fraction per kelvin the same runs at 26 degC show (0.41-0.45 %/K)."""
    warm = robot_bags(tmp_path / 'warm', [], temps=(50.0, 26.0, 38.0))
    warm_runs = [R.read_residual_run(p) for p in warm]
    doc = R.energy_loop_from_runs(bench['model'], copy.deepcopy(warm_runs), None,
                                  temp_ref_c=bench['temp_ref_c'])
    assert doc['effects_added'] == ['hot_windings']
    per_k = added(doc, 'hot_windings')['params']['per_k']
    truth = []
    for rw, rc in zip(warm_runs, clean_read):
        dt = (rw.temp_sum_c[0] - rc.temp_sum_c[0]) / rw.servo_count
        if abs(dt) > 1.0:
            truth.append((np.mean(rw.power_w) / np.mean(rc.power_w) - 1.0) / dt)
    assert len(truth) == 2
    assert min(truth) * 0.85 <= per_k <= max(truth) * 1.15, (per_k, truth)
    h = doc['heldout']
    assert h['rmse_after'] < 0.25 * h['rmse_before']


def test_paper_load_convention_fits_the_simulated_robot(bench, clean, clean_runs):
    """The simulated robot's stance tips carry M g / L (its leg's weight included, as Eq. 4
    and a real robot): read at the paper's convention (bench load m_c) the clean runs' bias is
    small (-0.24 W of 27-45 W) and no effect is added. The old simulator's tips carried
    m_leg g less and needed --load-offset = m_leg; that offset now under-predicts the robot."""
    assert clean['effects_added'] == []
    assert abs(clean['baseline']['bias']) < 0.5
    old = R.energy_loop_from_runs(bench['model'], clean_runs, None, temp_ref_c=bench['temp_ref_c'],
                                  load_offset_kg=LEG_KG)
    assert old['baseline']['bias'] > clean['baseline']['bias'] + 0.3


def test_time_offset_is_found_in_the_per_sample_view(bench, clean, tmp_path):
    """Half-cycle means cannot see a 50 ms clock shift of /battery_state; the per-sample view
    (Eq. 1 + the joints' drive-feature shape) selects time_offset, first, with its lag within
    20 % and the per-sample held-out RMSE down by more than half."""
    doc = loop(bench, robot_bags(tmp_path, ['time_offset=0.05']))
    assert doc['effects_added'] == ['time_offset'], doc['summary']
    sv = doc['sample_view']
    assert sv['heldout_rmse_after'] <= 0.5 * sv['heldout_rmse_before']
    np.testing.assert_allclose(added(doc, 'time_offset')['params']['offset_s'], 0.05, rtol=0.2)
    rec = next(c for c in doc['candidates'] if c['name'] == 'time_offset')
    assert rec['selected'] and rec['view'] == 'per sample'
    assert 'realigning it reduced held-out per-sample error' in doc['summary']
    # clean data: the lag is sub-sample (no built-in 10 ms bias any more), nothing selected
    assert abs(clean['sample_view']['lag_s']) < 0.005
    assert not next(c for c in clean['candidates'] if c['name'] == 'time_offset')['selected']


def _cli(argv):
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(argv)
    return args.func(args)


def test_cli_writes_the_schema_and_plots(bench, effect_bags, tmp_path, capsys):
    bags = effect_bags(['supply_resistance=0.3'])     # the supply_resistance case's bags
    out = tmp_path / 'out'
    code = _cli(['residuals', '--bench', str(bench['path']), '--robot', *map(str, bags),
                 '--out', str(out)])
    assert code == 0
    doc = json.loads((out / 'residuals.json').read_text())
    assert doc['model'] == 'energy' and doc['unit'] == 'W'
    for part in ('baseline', 'final'):
        assert set(doc[part]) == {'rmse', 'mae', 'bias'}
    assert set(doc['heldout']) == {'rmse_before', 'rmse_after'}
    for c in doc['candidates']:
        assert {'name', 'heldout_rmse', 'delta_bic', 'selected', 'params', 'stderr'} <= set(c)
    names = {c['name'] for c in doc['candidates']}
    assert names == {'basal_power', 'thermal_drift', 'hot_windings', 'kinematic_error',
                     'supply_resistance', 'speed_friction', 'leg_anomaly', 'time_offset',
                     'carried_mass', 'power_gain', 'swing_reversal',
                     'standing_hold', 'cable_resistance',   # a cable after the monitor: review K
                     'stance_preload'}                       # legs fighting each other
    assert doc['effects_added'][0] == 'supply_resistance'
    assert 'reduced held-out error from' in doc['summary']
    for p in doc['plots']:
        assert (out / p).stat().st_size > 1000
    assert 'residual_regressors.png' in doc['plots']
    printed = capsys.readouterr()
    assert 'supply_resistance' in printed.out
    # a progress bar on stderr: bench and robot bags read, then the loop
    assert 'residuals: 100%' in printed.err


def test_bad_input_names_what_is_missing(bench, tmp_path, capsys):
    from hexapod_common.bags import BagWriter, new_msg, stamp

    robot = robot_bags(tmp_path / 'r', [], run_s=3.0)
    # a robot bag used as a bench bag: no sessions
    with pytest.raises(BagContentError, match='/bench/session'):
        R.run_energy_loop([robot[0]], robot, None)
    # a robot bag without /battery_state
    nobat = tmp_path / 'nobat'
    with BagWriter(nobat) as w:
        w.write('/servo_status', 'hexapod_interfaces/msg/ServoStatus', new_msg(
            'hexapod_interfaces/msg/ServoStatus', header=stamp(1_000_000_000)), 1_000_000_000)
    with pytest.raises(BagContentError, match='/battery_state'):
        R.read_residual_run(nobat)
    # 3 s runs: too little to split
    with pytest.raises(R.ResidualDataError, match='too little'):
        loop(bench, robot)
    code = _cli(['residuals', '--bench', str(bench['path']), '--robot', str(nobat),
                 '--out', str(tmp_path / 'o')])
    assert code == 2
    assert '/battery_state' in capsys.readouterr().err


def _without_gait_phase(src: Path, dst: Path) -> Path:
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Writer

    from hexapod_common.bags import typestore

    store = typestore()
    with AnyReader([src], default_typestore=store) as r, Writer(dst, version=8) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in r.connections if c.topic != '/gait/phase'}
        for c, t, raw in r.messages():
            if c.id in conns:
                w.write(conns[c.id], t, raw)
    return dst


def test_bags_without_gait_phase_with_the_gait_given(bench, effect_bags, effect_loop, tmp_path):
    """Another lab's robot bags (no /gait/phase: its own gait code): with the gait given
    (--gait tripod --duty-factor 0.5 --step-length 0.1) the cycles come from the joints and the
    loop finds the same effect as on the bags with the schedule; without it the error says
    what to give."""
    bags = effect_bags(['basal_power=3'])
    bare = [_without_gait_phase(b, tmp_path / f'bare{i}') for i, b in enumerate(bags)]
    with pytest.raises(BagContentError, match='give --gait, --duty-factor and --step-length'):
        R.read_residual_run(bare[0])
    gait = R.GivenGait('tripod', 0.5, 0.10)
    runs = [R.read_residual_run(p, gait=gait) for p in bare]
    assert runs[0].leg_names == ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    assert 'cycles and period from the joint positions' in runs[0].notes[0]
    doc = R.energy_loop_from_runs(bench['model'], runs, None, temp_ref_c=bench['temp_ref_c'])
    ref = effect_loop(['basal_power=3'])           # loop(bench, bags)
    # (kinematic_error, speed_friction, basal_power and carried_mass are all smooth in step
    # frequency: with three frequencies their split is not identifiable, so the test takes
    # the effect whose regressor no other shares)
    assert doc['effects_added'][0] == ref['effects_added'][0] == 'basal_power'
    np.testing.assert_allclose(added(doc, 'basal_power')['params']['power_w'], 3.0, rtol=0.2)
    np.testing.assert_allclose(doc['baseline']['bias'], ref['baseline']['bias'], atol=0.1)
    assert doc['heldout']['rmse_after'] <= 0.5 * doc['heldout']['rmse_before']


def test_thermal_drift_without_servo_temperatures(bench, tmp_path):
    """Bags without /servo_status (another lab's servos, no ServoStatus): the servos' heating
    is still found, through the energy drawn since each run started (faster runs heat faster).
    Truth from the simulator's own temperatures: 0.05 W/K times the temperature rise per kJ
    drawn, 0.69-0.78 W/kJ over the three runs."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Writer

    from hexapod_common.bags import typestore

    bags = robot_bags(tmp_path / 'hot', ['thermal_drift=0.05'], run_s=60.0)
    store = typestore()
    bare, truth = [], []
    for i, b in enumerate(bags):
        r = R.read_residual_run(b)
        energy_kj = np.trapezoid(r.power_w, r.t_s) / 1000.0
        rise_k = np.polyfit(r.t_s - r.t_s[0], r.temp_sum_c, 1)[0] * (r.t_s[-1] - r.t_s[0])
        truth.append(0.05 * rise_k / energy_kj)
        dst = tmp_path / f'bare{i}'
        with AnyReader([b], default_typestore=store) as rd, Writer(dst, version=8) as w:
            conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                     for c in rd.connections if c.topic != '/servo_status'}
            for c, t, raw in rd.messages():
                if c.id in conns:
                    w.write(conns[c.id], t, raw)
        bare.append(dst)
    doc = loop(bench, bare)
    first = doc['added_params'][0]
    assert first['name'] == 'thermal_drift' and 'w_per_kj' in first['params'], doc['summary']
    np.testing.assert_allclose(first['params']['w_per_kj'], np.mean(truth), rtol=0.25)
    assert doc['heldout']['rmse_after'] <= 0.5 * doc['heldout']['rmse_before']


def test_hidden_offsets_and_gains_are_not_confidently_misnamed(bench, clean_read):
    """An outside review's cases (effects outside the catalogue, hidden in the robot bags):
    - the model over-predicting by 1 W (robot servos 1 K cooler than the bench's): it was named
      thermal_drift (the near-constant temperature column stood for an offset); now nothing is
      added and the leftover is reported: 'the model over-predicts every run';
    - a current sensor reading 5 % high: it was a 0.72 kg payload with no alternative; the
      summary now names power_gain (the gain) beside what is added."""
    runs = copy.deepcopy(clean_read)
    for r in runs:
        r.current_a = r.current_a - 1.0 / r.voltage_v
        r.power_w = r.voltage_v * r.current_a
    doc = R.energy_loop_from_runs(bench['model'], runs, None, temp_ref_c=bench['temp_ref_c'])
    assert 'thermal_drift' not in doc['effects_added'], doc['summary']
    assert doc['unexplained']['significant'] and 'over-predicts every run' in doc['summary']
    runs = copy.deepcopy(clean_read)
    for r in runs:
        r.current_a = 1.05 * r.current_a
        r.power_w = r.voltage_v * r.current_a
    doc = R.energy_loop_from_runs(bench['model'], runs, None, temp_ref_c=bench['temp_ref_c'])
    assert 'power_gain' not in doc['effects_added']        # named, never added
    first = doc['added_params'][0]
    gains = [a for a in first.get('alternatives', []) if a['name'] == 'power_gain']
    assert gains, doc['summary']
    assert 'power_gain (gain_excess = ' in doc['summary']


def test_battery_stamps_jittered_against_the_gait(bench, clean_bags, tmp_path):
    """Battery and gait stamped apart (+-0.5 ms, any real robot; the simulator stamps both on
    the same instants): the half-cycle windows are means over the exact half cycles, so the
    windows' noise stays near the exact stamps' (0.017 W) instead of 0.32 W, and clean runs
    stay clean (an outside review: the jitter hid a 1.5 W fan the exact stamps showed)."""
    from hexapod_common.testbags import rewrite_bag

    rng = np.random.default_rng(5)

    def jitter(topic, msg):
        if topic == '/battery_state':
            ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            ns += int(rng.uniform(-5e5, 5e5))
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)

    bags = [rewrite_bag(p, tmp_path / p.name, jitter, topics={'/battery_state'})
            for p in clean_bags]
    doc = loop(bench, bags)
    u = doc['unexplained']
    print(f"\njittered clean: final {u['rmse_w']:.3f} W, noise {u['noise_w']:.3f} W")
    assert u['noise_w'] < 0.08 and not u['significant']
    assert doc['effects_added'] == [] or doc['heldout']['rmse_before'] < 0.2


def test_a_bag_too_short_for_one_window_is_named(bench, clean_bags, tmp_path):
    """A 0.6 s robot bag gave numpy's 'need at least one array to concatenate' alone and an
    IndexError (exit 1) beside other bags (outside review); now a refusal naming the bag."""
    short = tmp_path / 'short'
    write_trace(simulate_robot(0.6, RobotConfig(period_s=0.5), seed=60), short)
    for bags in ([short], [short, *clean_bags]):
        with pytest.raises(R.ResidualDataError, match=r'short: 0\.\d+ s of battery data, too '
                                                       r'short for the loop'):
            loop(bench, bags)


def test_legs_the_half_cycle_windows_cannot_tell_apart_are_named():
    """Across runs of several gaits no two legs have equal in-stance fractions, so an anomaly
    was named on one leg with ``same_stance_as: []`` (outside review: L2 for R3). Legs whose
    fractions follow each other within every run are now named with it."""
    from hexapod_energy.effects_catalogue import LegAnomaly, WindowTable

    n = 40
    half = np.tile([1.0, 0.0], n // 2)
    run = np.repeat([0, 1], n // 2)
    # L1 and R3 swing in the same half of each run, at other fractions in the two runs
    frac = np.column_stack([np.where(run == 0, 0.5 + 0.5 * half, 0.67 + 0.33 * half),
                            1.0 - half, 0.5 + 0.0 * half, 0.5 + 0.0 * half, 1.0 - half,
                            np.where(run == 0, 0.4 + 0.5 * half, 0.7 + 0.3 * half)])
    table = WindowTable(
        run=run, t_s=np.tile(np.arange(n // 2) * 0.5, 2), duration_s=np.full(n, 0.5),
        measured_w=np.full(n, 31.0), predicted_w=np.full(n, 30.0),
        step_frequency_hz=np.ones(n), speed_mps=np.full(n, 0.1), current_sq_a2=np.ones(n),
        temp_excess_k=np.full(n, np.nan), stance_fraction=frac,
        leg_names=('L1', 'L2', 'L3', 'R1', 'R2', 'R3'))
    params, _ = LegAnomaly(leg_index=0, leg='L1').params(np.array([1.0]), np.array([0.1]),
                                                          table)
    assert params['same_stance_as'] == ['R3']


def test_an_effect_at_the_top_of_its_range_says_so():
    """hot_windings sat at its 1 %/K bound (0.01 +- 0.0016) without a word (outside review):
    an effect whose coefficient reaches its upper bound is marked and the summary says the
    residual asks for more than it can give."""
    from hexapod_energy.effects_catalogue import HotWindings, WindowTable

    n = 60
    run = np.repeat([0, 1, 2], n // 3)
    dt = np.repeat([20.0, 0.0, 10.0], n // 3) + np.tile(np.linspace(0, 2, n // 3), 3)
    pred = np.repeat([30.0, 35.0, 45.0], n // 3)
    measured = pred * (1 + 0.03 * dt) + np.random.default_rng(0).normal(0, 0.02, n)
    table = WindowTable(
        run=run, t_s=np.tile(np.arange(n // 3) * 0.5, 3), duration_s=np.full(n, 0.5),
        measured_w=measured, predicted_w=pred, step_frequency_hz=np.ones(n),
        speed_mps=np.full(n, 0.1), current_sq_a2=np.ones(n), temp_excess_k=18 * dt,
        stance_fraction=np.full((n, 6), 0.5), leg_names=('L1', 'L2', 'L3', 'R1', 'R2', 'R3'),
        extra={'temp_excess_mean_k': dt, 'winding_excess_w': dt * pred})
    held = np.tile(np.arange(n // 3) % 3 == 2, 3)
    sel = R.EffectSelection(catalogue=[HotWindings()]).fit(table, held)
    doc = R.energy_loop_document(table, sel, held)
    [hot] = doc['added_params']
    assert hot['params']['per_k'] == pytest.approx(0.01) and hot['at_bound'] == 'upper'
    assert 'at the top of its physical range' in doc['summary']
