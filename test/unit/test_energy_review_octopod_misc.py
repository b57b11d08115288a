"""Outside review (octopod lab), the medium and low findings:

* B2: ``--robot-mass 3200`` (grams) was taken as 3200 kg (SR and CoT/M 1000x low);
* B3: ``--recommend`` priced every candidate at AntBot's 40 mm lift whatever the robot's
  (+4.3 % for a robot lifting 30 mm), and the JSON did not say which lift;
* B4: the breakdown's ``holding_w`` held the basal power at the bench's heaviest load while
  Eq. 1 extrapolated (9.6 W for 13.2 W at 1.4 kg on a 0-0.8 kg bench);
* C2: a current sign forced wrong left efficiency, CoT and SR negative in ``energy.json``;
* C4: an end-of-plan ``done`` marker under its own session id was warned as a session that
  never walked, with "-0.0 s" of data;
* C5: "Oktopus-8 leg's leg", and no note that P_out came from the model with ``--leg``.
"""

from __future__ import annotations

import json
import math
import types

import numpy as np
import pytest

from hexapod_common.testbags import write_foreign_robot_bag as write_bag
from hexapod_energy import cli
from hexapod_energy.bag_io import _repair_sessions
from hexapod_energy.descriptors import descriptors_from_powers
from hexapod_energy.single_leg import SingleLegModel


@pytest.fixture(scope='module')
def robot_bag(tmp_path_factory):
    root = tmp_path_factory.mktemp('octopod_misc')
    write_bag(root / 'robot', legs=6, duration_s=10.0, storage='mcap', sign=1.0)
    return root / 'robot'


def test_a_robot_mass_in_grams_is_refused(robot_bag, tmp_path, capsys):
    code = cli.main(['--robot', str(robot_bag), '--robot-mass', '3200', '--no-progress',
                     '--out', str(tmp_path / 'o')])
    assert code == 2
    err = capsys.readouterr().err
    assert 'grams' in err and '3.2 kg' in err and f'{cli.ROBOT_MASS_MAX_KG:g} kg' in err
    assert cli.main(['--robot', str(robot_bag), '--robot-mass', '3.2', '--no-progress',
                     '--out', str(tmp_path / 'ok')]) == 0


def test_recommend_prices_the_robots_own_lift(monkeypatch):
    seen = {}

    def fake(model, opm, **kw):
        seen.update(kw)
        return types.SimpleNamespace(to_dict=lambda: {'step_height_m': kw['step_height_m']},
                                     note='', saving_fraction=None)

    import hexapod_energy.recommend as rec
    monkeypatch.setattr(rec, 'recommend_gait', fake)
    args = types.SimpleNamespace(speed=0.1, payload=0.0, load_offset=0.0)
    setup = types.SimpleNamespace(limits=None, limits_source='default')
    doc = {'robot_runs': [{'step_height_m': 0.03}, {'step_height_m': 0.03},
                          {'step_height_m': None}]}
    cli._recommendation(args, doc, None, None, 8, 'robot runs', setup)
    assert seen['step_height_m'] == pytest.approx(0.03)
    assert doc['recommendation']['step_height_m'] == pytest.approx(0.03)
    assert 'robot runs' in doc['recommendation']['step_height_source']
    doc = {}
    cli._recommendation(args, doc, None, None, 8, 'default', setup)
    assert seen['step_height_m'] == pytest.approx(0.04)
    assert 'default' in doc['recommendation']['step_height_source']


def test_recommend_gait_writes_the_lift_it_priced():
    from dataclasses import fields

    from hexapod_energy.recommend import Candidate, Recommendation
    assert 'step_height_m' in {f.name for f in fields(Candidate)}
    assert 'step_height_m' in {f.name for f in fields(Recommendation)}


def test_holding_extrapolates_the_basal_power_as_eq1_does():
    model = SingleLegModel()
    model.basal_power_w_ = {0.0: 1.2, 0.2: 1.8, 0.4: 2.4, 0.6: 3.0, 0.8: 3.6}
    assert model.basal_power_at_w(1.4) == pytest.approx(5.4, rel=1e-12)
    assert model.basal_power_at_w(0.3) == pytest.approx(2.1, rel=1e-12)
    assert model.basal_power_at_w(-0.2) == pytest.approx(0.6, rel=1e-12)
    model.basal_power_w_ = {0.4: 2.4}
    assert model.basal_power_at_w(1.4) == pytest.approx(2.4)


def test_a_negative_input_power_gives_no_costs(robot_bag, tmp_path):
    d = descriptors_from_powers(power_in_w=-36.0, power_out_w=7.5, speed_mps=0.16,
                                mass_kg=3.2)
    assert all(math.isnan(x) for x in (d.efficiency, d.cost_of_transport_j_per_m,
                                       d.specific_cost_of_transport, d.specific_resistance))
    # positive discharge forced to the ROS sign: P_in negative, nothing divided by it
    assert cli.main(['--robot', str(robot_bag), '--robot-mass', '2', '--current-sign', 'ros',
                     '--no-progress', '--out', str(tmp_path / 'o')]) == 0
    [r] = json.loads((tmp_path / 'o' / 'energy.json').read_text())['robot_runs']
    assert r['measured_power_in_w'] < 0
    for key in ('efficiency', 'cost_of_transport', 'specific_cost_of_transport',
                'specific_resistance'):
        assert r[key] is None, key


def test_an_end_of_plan_marker_is_noted_not_warned():
    f, t_end = 1.0, 9.0
    t = np.arange(0.0, t_end, 0.005)
    ph = (t * f) % 1.0
    z = np.where(ph >= 0.5, 0.04 * np.sin(np.pi * (ph - 0.5) / 0.5), 0.0)
    ses = [{'t_s': 0.0, 'session_id': 's1', 'state': 'walking', 'load_kg': 0.1,
            'frequency_hz': f, 'duty_factor': 0.5},
           {'t_s': t_end, 'session_id': 's1', 'state': 'cooling', 'load_kg': 0.1,
            'frequency_hz': f, 'duty_factor': 0.5},
           {'t_s': t_end + 0.01, 'session_id': 'plan', 'state': 'done', 'load_kg': 0.1,
            'frequency_hz': f, 'duty_factor': 0.5}]
    notes, warnings = [], []
    _repair_sessions(ses, list(zip(t, z)), 0.0, t_end, notes, warnings)
    assert not any('never reports state walking' in w for w in warnings), warnings
    text = ' '.join(notes)
    assert 'end-of-plan marker' in text and '-0.0' not in text


def test_the_model_p_out_is_noted_once_named(monkeypatch):
    args = types.SimpleNamespace(power_out='auto', leg='oct.yaml')
    run_ = types.SimpleNamespace(power_out_w=math.nan, power_in_w=36.0, extra={})
    for name, whose in (('Oktopus-8 leg', 'of Oktopus-8 leg ('), ('AntBot', "AntBot's leg")):
        setup = types.SimpleNamespace(leg=types.SimpleNamespace(name=name))
        notes: list[str] = []
        p, source = cli._chosen_power_out(args, setup, run_, 0.56, False, 3.2, notes, {}, 'b')
        assert (p, source) == (0.56, 'model')
        text = ' '.join(notes)
        assert 'from the Eq. 6 model' in text and whose in text
        assert "leg's leg" not in text
