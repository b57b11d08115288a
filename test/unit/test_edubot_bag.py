"""EduBot runs written into bags: topics, counts, metadata (effects + truth), CLI errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose
from ruamel.yaml import YAML

from hexapod_bench_drivers.edubot_bag import EFFECTS_KEY, TRUTH_KEY, main, write_run
from hexapod_bench_drivers.edubot_sim import simulate_edubot
from hexapod_common.bags import open_reader


def test_bag_has_the_five_topics_and_truth_only_in_metadata(tmp_path):
    run = simulate_edubot('pace', duration_s=3.0, seed=2, effects={'leg_damping': 20.0})
    path = write_run(tmp_path / 'bag', run)
    reader = open_reader(path)
    try:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {'/joint_states': 300, '/joint_commands': 300, '/gait/phase': 300,
                          '/battery_state': 300, '/mocap/body': len(run.mocap_t_s)}
        meta = YAML(typ='safe').load((path / 'metadata.yaml').read_text(encoding='utf8'))
        custom = meta['rosbag2_bagfile_information']['custom_data']
        effects = json.loads(custom[EFFECTS_KEY])
        assert effects['leg_damping'] == {'value': 20.0, 'unit': 'N s/m'}
        assert 'hip_torque' not in effects          # off effects are not listed
        truth = json.loads(custom[TRUTH_KEY])
        assert truth['single_support'] == run.truth['single_support']
        js = [reader.deserialize(d, c.msgtype) for c, _, d in reader.messages(
            connections=[c for c in reader.connections if c.topic == '/joint_states'])]
        batt = [reader.deserialize(d, c.msgtype) for c, _, d in reader.messages(
            connections=[c for c in reader.connections if c.topic == '/battery_state'])]
    finally:
        reader.close()
    assert list(js[0].name) == ['L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip']
    assert_allclose(np.stack([m.position for m in js]), run.hip_position_rad)
    assert_allclose([m.current for m in batt], run.battery_current_a, rtol=1e-6)
    assert np.mean([m.current < 0 for m in batt]) > 0.95    # discharging (brief regen aside)


def test_cli_writes_runs_and_refuses_bad_effects(tmp_path, capsys):
    assert main(['edubot', '--out', str(tmp_path / 'runs'), '--gait', 'walk', '--duration',
                 '2', '--runs', '2', '--effect', 'mocap_noise=0']) == 0
    assert (tmp_path / 'runs' / 'run_000' / 'metadata.yaml').is_file()
    assert (tmp_path / 'runs' / 'run_001' / 'metadata.yaml').is_file()
    assert main(['edubot', '--out', str(tmp_path / 'x'), '--effect', 'leg_dampng=3']) == 2
    assert "unknown effect 'leg_dampng'" in capsys.readouterr().err
    assert main(['edubot', '--out', str(tmp_path / 'runs')]) == 2   # exists
    with pytest.raises(SystemExit):
        main(['edubot', '--out', str(tmp_path / 'y'), '--gait', 'gallop'])
