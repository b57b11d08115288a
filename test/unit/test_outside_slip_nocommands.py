"""Another lab's RHex-class bag without ``/joint_commands`` (their controller does not log the
Buehler clock's target speeds): the geometric stance edges need only hip angles, motion
capture and the leg description, so ``slip`` fits the same stances as with the commands; the
paper's shifted-clock edges are absent (noted), and asking for them is refused by name.
Before, the bag was refused for the missing topic."""

from __future__ import annotations

import argparse
import json

import pytest

from hexapod_common.bags import BagWriter, iter_messages, open_reader
from slip_identification.cli import add_cli, read_run
from slip_identification.errors import SlipDataError
from slip_identification.geometry import LegGeometry
from slip_identification.pipeline import analyze_run

edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')


def _slip(tmp_path, bag, name, *extra):
    ap = argparse.ArgumentParser()
    add_cli(ap.add_subparsers(dest='command', required=True))
    args = ap.parse_args(['slip', str(bag), '--out', str(tmp_path / name), *extra])
    code = args.func(args)
    return code, json.loads((tmp_path / name / 'slip.json').read_text())


def test_slip_without_joint_commands(tmp_path):
    ref = edubot_bag.write_edubot_bag(tmp_path / 'ref', 'running', duration_s=3.0, seed=1)
    lab = tmp_path / 'lab'
    with open_reader(ref) as reader, BagWriter(lab) as writer:
        for m in iter_messages(reader, ['/joint_states', '/mocap/body', '/battery_state']):
            writer.write(m.topic, m.msgtype, m.data, m.stamp_ns)
    code_ref, doc_ref = _slip(tmp_path, ref, 'o_ref')
    code, doc = _slip(tmp_path, lab, 'o_lab')
    assert code == code_ref == 0
    assert len(doc['stances']) == len(doc_ref['stances']) >= 5
    for a, b in zip(doc['stances'], doc_ref['stances']):
        assert a['touchdown'] == pytest.approx(b['touchdown'], abs=1e-9)
        assert a['stiffness'] == pytest.approx(b['stiffness'], rel=1e-9)
    (run,) = doc['runs']
    assert run['paper_edges'] == [] and run['edges'] == 'geometry'
    assert any('/joint_commands' in n for n in run['notes'])
    data = read_run(lab)
    assert data.command_t_s.size == 0
    with pytest.raises(SlipDataError, match='joint commands'):
        analyze_run(data, edges='paper', geometry=LegGeometry())
