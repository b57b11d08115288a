"""``hexapod-analyze slip`` on another RHex-class robot: its leg size and hip positions given on
the command line (--leg-radius, --hip-x) instead of the EduBot defaults."""

from __future__ import annotations

import dataclasses
import json

import pytest

from hexapod_bench_drivers import edubot_sim
from hexapod_common.analyze_cli import main as analyze_main


def _ground_truth(bag) -> float:
    import yaml

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    truth = json.loads(meta['custom_data']['hexapod_sim.edubot_truth'])
    return truth['frame']['ground_plane_z_m'], truth['clock_offset_s']


def test_other_leg_size_given_on_the_command_line(tmp_path) -> None:
    # a bigger robot: 0.13 m leg chord (EduBot 0.105) and hips 0.24 m fore and aft
    params = dataclasses.replace(edubot_sim.EdubotParams(), leg_rest_length_m=0.13,
                                 hip_x_m=(0.24, 0.0, -0.24))
    bag = edubot_sim.write_edubot_bag(tmp_path / 'big', 'running', duration_s=4.5, seed=1,
                                      params=params)
    ground, offset = _ground_truth(bag)
    # without figures (--no-plots): the test reads slip.json only
    rc = analyze_main(['slip', str(bag), '--out', str(tmp_path / 'given'), '--no-plots',
                       '--leg-radius', '0.065', '--hip-x', '0.24', '0', '-0.24'])
    assert rc == 0
    run = json.loads((tmp_path / 'given' / 'slip.json').read_text())['runs'][0]
    assert run['geometry']['leg_radius_m'] == pytest.approx(0.065)
    assert run['geometry']['hip_x_m'] == [0.24, 0.0, -0.24]
    assert run['offset_method'] == 'geometry'
    assert abs(run['ground_m'] - ground) < 0.002
    assert abs(run['offset_s'] - offset) < 0.003      # 2.1 ms on this seed
    # with the EduBot's legs assumed instead, the ground is off by about the leg size difference
    analyze_main(['slip', str(bag), '--out', str(tmp_path / 'default'), '--no-plots'])
    wrong = json.loads((tmp_path / 'default' / 'slip.json').read_text())['runs'][0]
    assert wrong['geometry']['leg_radius_m'] == pytest.approx(0.0525)
    assert abs(wrong['ground_m'] - ground) > 0.01


def test_bad_geometry_options_are_refused(tmp_path, capsys) -> None:
    rc = analyze_main(['slip', str(tmp_path / 'nobag'), '--out', str(tmp_path / 'o'),
                       '--hip-x', '0', '0.2', '-0.2'])
    assert rc != 0
    assert 'front > middle > rear' in capsys.readouterr().err
