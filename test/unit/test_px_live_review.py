"""An outside review: a PhantomX-class lab (52/66/133 mm, 0.175 kg legs) ran the live graph
(``sim_robot``, ``gait_scheduler``, ``energy_monitor``, ``bag_recorder``, all ``-p
leg_file``) and ``hexapod-analyze energy --leg`` on the bag.

- The robot mass nobody gave: ``sim_robot -p leg_file`` and ``hexapod-sim robot --leg`` walk
  AntBot's body with the file's legs (2.237 kg), but ``hexapod-analyze energy --leg`` (and
  ``residuals --leg``) on a bag that declares no mass (``bag_recorder``'s) assumed AntBot's
  2.183 kg: the Eq. 6 P_out 0.522 W for the 0.526 W of the robot walked at 0.2 m/s, CoT/M
  72.9 for 71.2 J/(m kg), with exit 0. One rule now (``kinematics.default_robot_mass_kg``).
- ``gait_scheduler``'s stand keeps its period (step length and height 0): the live
  ``energy_monitor`` read it as a Buehler clock (P_out NaN, a note about rotating legs), while
  ``energy`` reads the same stand as P_out 0 W.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

LEG_YAML = """name: review PX leg
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.030, 0.065, 0.080]
neutral_tip_m: [0.125, 0.0, -0.095]
"""
LEG_KG = 0.175
#: AntBot's body (2.183 kg less six 0.166 kg legs) with six of this leg
ROBOT_KG = 2.183 - 6 * (0.01498 + 0.1118 + 0.03923) + 6 * LEG_KG


def _stand(period_s: float = 1.0):
    from hexapod_common.conversions import GaitPhaseSample

    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    return GaitPhaseSample(t_s=1.0, gait='tripod', period_s=period_s, duty_factor=0.5,
                           step_length_m=0.0, step_height_m=0.0, sweep_angle_rad=0.0,
                           leg_offset_rad=0.0, cycle_phase=0.3, leg_names=legs,
                           phase_offsets=np.array([0, .5, 0, .5, 0, .5]),
                           in_stance=np.ones(6, bool), supporting_legs=6)


def test_the_assumed_mass_of_a_leg_file_robot_is_the_simulators() -> None:
    from hexapod_bench_drivers.robot_sim import default_robot_mass_kg as sim_rule
    from hexapod_energy.bag_io import resolve_robot_mass
    from hexapod_gait.kinematics import default_robot_mass_kg

    assert sim_rule is default_robot_mass_kg
    assumed = resolve_robot_mass(None, [], leg_mass_kg=LEG_KG)
    assert assumed.kg == pytest.approx(ROBOT_KG, abs=1e-9) and assumed.assumed
    assert 'leg' in assumed.source
    four = resolve_robot_mass(None, [], leg_mass_kg=LEG_KG, leg_count=4)
    assert four.kg == pytest.approx(default_robot_mass_kg(4, LEG_KG), abs=1e-12)
    assert resolve_robot_mass(None, []).kg == 2.183


@pytest.fixture(scope='module')
def undeclared_bag(tmp_path_factory):
    """A simulated PhantomX-class robot's bag whose metadata declares no mass (as a
    bag_recorder bag of the live graph)."""
    from hexapod_bench_drivers.sim_cli import main as sim_main

    d = tmp_path_factory.mktemp('px_live')
    (d / 'px.yaml').write_text(LEG_YAML)
    assert sim_main(['robot', '--out', str(d / 'run'), '--duration', '3', '--no-progress',
                     '--speed', '0.2', '--leg', str(d / 'px.yaml')]) == 0
    meta_path = d / 'run' / 'metadata.yaml'
    meta = yaml.safe_load(meta_path.read_text())
    custom = meta['rosbag2_bagfile_information']['custom_data']
    config = json.loads(custom['hexapod_sim.config'])
    assert config['robot_mass_kg'] == pytest.approx(ROBOT_KG, abs=1e-9)
    del config['robot_mass_kg']
    custom['hexapod_sim.config'] = json.dumps(config)
    meta_path.write_text(yaml.safe_dump(meta))
    return d


def test_energy_with_a_leg_file_assumes_antbots_body_with_its_legs(undeclared_bag, tmp_path,
                                                                   capsys) -> None:
    from hexapod_energy.cli import main as energy_main

    d = undeclared_bag
    rc = energy_main(['--out', str(tmp_path / 'e'), '--no-progress', '--robot',
                      str(d / 'run'), '--leg', str(d / 'px.yaml'), '--power-out', 'model'])
    err = capsys.readouterr().err
    assert rc == 0, err
    doc = json.loads((tmp_path / 'e' / 'energy.json').read_text())
    assert doc['robot_mass']['kg'] == pytest.approx(ROBOT_KG, abs=1e-9), doc['robot_mass']
    run = doc['robot_runs'][0]
    assert run['mass_kg'] == pytest.approx(ROBOT_KG, abs=1e-9)
    warning = next(w for w in doc['warnings'] if 'robot mass not given' in w)
    assert '2.183' not in warning and '2.237' in warning and '0.175 kg legs' in warning
    # the README's definitions: CoT/M = P_loss / (M v), SR = P_in / (M g v), M the mass
    v, p_in, p_out = run['speed'], run['measured_power_in_w'], run['power_out_w']
    assert run['specific_cost_of_transport'] == pytest.approx((p_in - p_out) / (ROBOT_KG * v),
                                                              rel=1e-9)
    assert run['specific_resistance'] == pytest.approx(p_in / (ROBOT_KG * 9.81 * v), rel=1e-3)


def test_a_stand_that_keeps_its_period_is_not_a_buehler_clock() -> None:
    from hexapod_energy.descriptors import is_clock_schedule, model_power_out
    from hexapod_energy.leg_description import antbot_leg

    stand = _stand(1.0)
    assert not is_clock_schedule(stand)
    assert not is_clock_schedule(_stand(0.0))
    model = model_power_out(antbot_leg().output_power_model(2.183), robot_mass_kg=2.183)
    assert model(stand, 2.183) == 0.0
    # a Buehler clock stays one
    from dataclasses import replace
    assert is_clock_schedule(replace(stand, gait='buehler', sweep_angle_rad=1.0))
