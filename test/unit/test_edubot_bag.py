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


def test_fast_encoders_write_the_bytes_rosbags_writes(tmp_path):
    """Every raw message in the bag equals rosbags' serialisation of the same message."""
    from hexapod_common.bags import new_msg, stamp, typestore

    run = simulate_edubot('running', duration_s=2.5, seed=4)
    path = write_run(tmp_path / 'bag', run)
    store = typestore()
    names = [f'{leg}_hip' for leg in run.leg_names]
    seen: dict[str, int] = {}
    with open_reader(path) as reader:
        for conn, t_ns, raw in reader.messages():
            topic = conn.topic
            k = seen.get(topic, 0)
            seen[topic] = k + 1
            if k % 37:                      # a spread sample of each topic is enough
                continue
            hdr = stamp(t_ns, '')
            if topic == '/mocap/body':     # stamped in the mocap clock, received at true time
                stamp_ns = int(round(run.mocap_t_s[k] * 1e9))
                assert stamp_ns - t_ns == pytest.approx(run.effects['time_offset'] * 1e9, abs=2)
                hdr = stamp(stamp_ns, 'mocap')
            if topic == '/joint_states':
                msg = new_msg(conn.msgtype, header=hdr, name=names,
                              position=run.hip_position_rad[k],
                              velocity=run.hip_velocity_rad_s[k], effort=run.hip_effort_nm[k])
            elif topic == '/joint_commands':
                msg = new_msg(conn.msgtype, header=hdr, name=names,
                              position=run.target_position_rad[k],
                              velocity=run.target_velocity_rad_s[k])
            elif topic == '/battery_state':
                v = float(run.battery_voltage_v[k])
                msg = new_msg(conn.msgtype, header=hdr, voltage=v, temperature=np.nan,
                              current=float(run.battery_current_a[k]), charge=np.nan,
                              capacity=np.nan, design_capacity=1.32, percentage=np.nan,
                              power_supply_status=2, power_supply_health=1,
                              power_supply_technology=3, present=True,
                              cell_voltage=np.full(4, v / 4), location='edubot')
            elif topic == '/mocap/body':
                p, q = run.mocap_position_m[k], run.mocap_quat_xyzw[k]
                msg = new_msg(conn.msgtype, header=hdr, pose=new_msg(
                    'geometry_msgs/msg/Pose',
                    position=new_msg('geometry_msgs/msg/Point', x=p[0], y=p[1], z=p[2]),
                    orientation=new_msg('geometry_msgs/msg/Quaternion', x=q[0], y=q[1],
                                        z=q[2], w=q[3])))
            else:
                decoded = store.deserialize_cdr(raw, conn.msgtype)
                assert decoded.gait == 'buehler'
                assert decoded.period == pytest.approx(run.clock.period_s)
                assert decoded.sweep_angle == pytest.approx(run.clock.sweep_angle_rad)
                assert list(decoded.leg_names) == list(run.leg_names)
                assert decoded.cycle_phase == pytest.approx(
                    (run.t_s[k] / run.clock.period_s) % 1.0)
                left = run.clock.in_slow_phase(run.t_s[k:k + 1], 'left')[0]
                right = run.clock.in_slow_phase(run.t_s[k:k + 1], 'right')[0]
                assert list(decoded.in_stance) == [left, right, left, right, left, right]
                assert decoded.supporting_legs == 3 * (int(left) + int(right))
                msg = decoded
            assert bytes(raw) == bytes(store.serialize_cdr(msg, conn.msgtype)), (topic, k)
    assert set(seen) == {'/joint_states', '/joint_commands', '/gait/phase', '/battery_state',
                         '/mocap/body'}
