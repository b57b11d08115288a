"""Another robot's leg for the Eq. 6 output-power model (``energy --leg FILE``): a PhantomX-like
leg (longer femur, heavier tibia, its own stance pose) gives its own P_out, equal to the model
built from that leg directly; bad files are refused naming the problem. Before, every robot's
modelled P_out was AntBot's leg's."""

from __future__ import annotations

import json

import pytest

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.leg_description import antbot_leg, load_leg_description
from hexapod_gait.gait import make_gait

PHANTOM = """
name: PhantomX-like
a_m: [0.052, 0.082, 0.155]
link_masses_kg: [0.025, 0.14, 0.09]
neutral_tip_m: [0.15, 0.0, -0.13]
"""


def test_leg_file_changes_the_modelled_output_power(tmp_path):
    f = tmp_path / 'phantom.yaml'
    f.write_text(PHANTOM)
    leg = load_leg_description(f)
    assert leg.name == 'PhantomX-like' and leg.spec.leg_mass_kg == pytest.approx(0.255)
    gait = make_gait('tripod', period_s=0.6)
    p_other = float(leg.output_power_model(2.5).power_out_w(gait))
    p_ant = float(antbot_leg().output_power_model(2.5).power_out_w(gait))
    assert p_other > 0 and abs(p_other / p_ant - 1) > 0.05
    # the same figure from a JSON file
    j = tmp_path / 'phantom.json'
    j.write_text(json.dumps({'a_m': [0.052, 0.082, 0.155], 'link_masses_kg': [0.025, 0.14, 0.09],
                             'neutral_tip_m': [0.15, 0.0, -0.13]}))
    assert float(load_leg_description(j).output_power_model(2.5).power_out_w(gait)) == \
        pytest.approx(p_other, rel=1e-12)


@pytest.mark.parametrize('text, match', [
    ('a_m: [0.05, 0.08]\nlink_masses_kg: [0.1, 0.1, 0.1]\nneutral_tip_m: [0.1, 0, -0.1]',
     'a_m must be 3 finite numbers'),
    ('a_m: [0.05, 0.08, 0.1]\nlink_masses_kg: [0.1, 0.1, 0.1]', "missing \\['neutral_tip_m'\\]"),
    ('a_m: [0.05, 0.08, 0.1]\nlink_mass: [0.1, 0.1, 0.1]\nneutral_tip_m: [0.1, 0, -0.1]',
     "unknown key\\(s\\) \\['link_mass'\\]"),
    ('a_m: [0.05, 0.03, 0.04]\nlink_masses_kg: [0.1, 0.1, 0.1]\nneutral_tip_m: [0.3, 0, -0.2]',
     'leave the leg workspace'),
    ('a_m: [0.05, 0.08, 0.1]\nlink_masses_kg: [0.1, -0.1, 0.1]\nneutral_tip_m: [0.1, 0, -0.1]',
     'link_masses_kg must be >= 0'),
    ('[1, 2', 'not YAML/JSON'),
])
def test_bad_leg_files_are_refused(tmp_path, text, match):
    f = tmp_path / 'leg.yaml'
    f.write_text(text)
    with pytest.raises(InvalidInputError, match=match):
        load_leg_description(f)


def test_energy_cli_uses_the_leg(tmp_path):
    from test_energy_cli import _write_bench

    from hexapod_common.analyze_cli import main as analyze
    from hexapod_common.testbags import write_two_battery_robot_bag

    f = tmp_path / 'phantom.yaml'
    f.write_text(PHANTOM)
    _write_bench(tmp_path / 'bench')
    write_two_battery_robot_bag(tmp_path / 'robot', logic_w=0.0)
    docs = {}
    for name, extra in (('ant', []), ('phantom', ['--leg', str(f)])):
        out = tmp_path / name
        assert analyze(['energy', '--bench', str(tmp_path / 'bench'), '--robot',
                        str(tmp_path / 'robot'), '--out', str(out), '--no-progress',
                        '--robot-mass', '2.5', *extra]) == 0
        docs[name] = json.loads((out / 'energy.json').read_text())
    assert docs['phantom']['leg']['name'] == 'PhantomX-like'
    assert docs['ant']['leg']['name'] == 'AntBot'
    ant, ph = docs['ant']['robot_runs'][0], docs['phantom']['robot_runs'][0]
    assert ph['power_out_source'] == ant['power_out_source'] == 'model'
    leg = load_leg_description(f)
    gait = make_gait('tripod', period_s=0.5, step_length_m=0.1)
    assert ph['power_out_model_w'] == pytest.approx(
        float(leg.output_power_model(2.5).power_out_w(gait)), rel=1e-9)
    assert ph['power_out_model_w'] != pytest.approx(ant['power_out_model_w'], rel=0.05)
