"""Outside review (octopod lab), A3: ``JointState.effort`` filled with 0.0 by a driver without
an effort interface gave P_out 0.0 W "from effort", efficiency 0 and no note, offline and
live alike (the PWM-load test is 0 / 0 there, so it passed). Now zero efforts are no efforts:
P_out from the Eq. 6 model when it can give one (else unknown), said in a note; the live
accumulator and the offline command agree."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from rosbags.rosbag2 import Writer

from hexapod_common.bags import iter_messages, open_reader
from hexapod_common.conversions import (
    battery_from_msg,
    gait_phase_from_msg,
    joint_state_from_msg,
)
from hexapod_common.testbags import foreign_typestore
from hexapod_common.testbags import write_foreign_robot_bag as write_bag
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.cli import main
from hexapod_energy.descriptors import (
    ZERO_EFFORT_NOTE,
    DescriptorAccumulator,
    model_power_out,
)
from hexapod_energy.leg_description import antbot_leg

MASS = 2.0


def _zero_efforts(src, dst, *, drop=False):
    """``src`` with every JointState's efforts set to 0.0 (``drop``: left empty)."""
    store = foreign_typestore()
    with open_reader(src) as reader, Writer(dst, version=9) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in reader.connections}
        for conn, t_ns, data in reader.messages():
            if conn.topic == '/joint_states':
                msg = store.deserialize_cdr(data, conn.msgtype)
                msg.effort = np.zeros(0 if drop else len(msg.name), dtype=np.float64)
                data = store.serialize_cdr(msg, conn.msgtype)
            w.write(conns[conn.id], t_ns, data)
    return dst


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('zero_effort')
    write_bag(root / 'src', legs=6, duration_s=12.0, storage='mcap')
    return _zero_efforts(root / 'src', root / 'zero'), _zero_efforts(root / 'src',
                                                                     root / 'none', drop=True)


def _live(path, *, with_model=True):
    model = model_power_out(antbot_leg().output_power_model(MASS), robot_mass_kg=MASS) \
        if with_model else None
    acc = DescriptorAccumulator(mass_kg=MASS, current_sign='auto', power_out_model=model,
                                power_out_source='auto')
    out = []
    conv = {'/battery_state': (battery_from_msg, acc.add_battery),
            '/gait/phase': (gait_phase_from_msg, acc.add_gait_phase),
            '/joint_states': (joint_state_from_msg, acc.add_joint_state)}
    with open_reader(path) as reader:
        for m in iter_messages(reader, tuple(conv)):
            make, add = conv[m.topic]
            out.extend(add(make(reader.deserialize(m.data, m.msgtype))) or ())
    return out


def test_offline_zero_efforts_are_no_efforts(bags):
    zero, _ = bags
    run = read_robot_bag(zero, mass_kg=MASS)
    assert math.isnan(run.power_out_w)
    assert any(n.startswith(ZERO_EFFORT_NOTE) for n in run.extra.get('notes', ())) or \
        any(n.startswith(ZERO_EFFORT_NOTE) for n in getattr(run, 'notes', ()))


def test_cli_takes_the_model_and_says_so(bags, tmp_path):
    zero, none = bags
    docs = {}
    for name, bag in (('zero', zero), ('none', none)):
        assert main(['--robot', str(bag), '--robot-mass', str(MASS),
                     '--no-progress', '--out', str(tmp_path / name)]) == 0
        docs[name] = json.loads((tmp_path / name / 'energy.json').read_text())
    [r] = docs['zero']['robot_runs']
    [ref] = docs['none']['robot_runs']
    assert r['power_out_source'] == 'model'
    assert r['power_out_w'] == pytest.approx(ref['power_out_w'], rel=1e-12)
    assert r['power_out_w'] > 0 and r['efficiency'] > 0
    text = ' '.join(r['notes'])
    assert ZERO_EFFORT_NOTE in text
    assert 'from the Eq. 6 model' in text and 'all 0.0' in text


def test_live_windows_take_the_model_as_without_efforts(bags):
    zero, none = bags
    got, ref = _live(zero), _live(none)
    assert len(got) == len(ref) >= 3
    for a, b in zip(got, ref):
        assert a.power_out_w == pytest.approx(b.power_out_w, rel=1e-12)
        assert a.power_out_w > 0
        assert any(w.startswith(ZERO_EFFORT_NOTE) and 'Eq. 6 model' in w for w in a.warnings)
    # no model: unknown, not 0 W
    bare = _live(zero, with_model=False)
    assert bare and all(math.isnan(d.power_out_w) for d in bare)
    assert all(math.isnan(d.efficiency) for d in bare)
