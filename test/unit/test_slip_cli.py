"""``hexapod-analyze slip`` on simulated EduBot bags: slip.json schema, plots, refusals."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from slip_identification.cli import add_cli

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _run(argv):
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(argv)
    return args.func(args)


def test_slip_command_writes_schema_and_refuses_missing_topic(tmp_path):
    good = edubot_sim.write_edubot_bag(tmp_path / 'run', 'running', duration_s=4.0, seed=1)
    # a bag without the mocap topic
    from hexapod_common.bags import BagWriter, new_msg, stamp
    bad = tmp_path / 'nomocap'
    with BagWriter(bad) as w:
        msg = new_msg('sensor_msgs/msg/BatteryState', header=stamp(1_000_000_000),
                      voltage=14.8, current=-2.0)
        w.write('/battery_state', 'sensor_msgs/msg/BatteryState', msg, 1_000_000_000)
    out = tmp_path / 'out'
    code = _run(['slip', str(good), str(bad), '--out', str(out), '--jobs', '2',
                 '--box', '-10', '-10', '-10', '10', '10', '10'])
    assert code == 0
    doc = json.loads((out / 'slip.json').read_text())
    assert doc['schema'] == 'slip/1'
    assert len(doc['stances']) >= 5
    s = doc['stances'][0]
    for key in ('touchdown', 'liftoff', 'tripod', 'stiffness', 'rest_length', 'foot_x',
                'stiffness_stderr', 'rest_length_stderr', 'foot_x_stderr', 'nerr', 'converged',
                'position_fit', 'start'):
        assert key in s
    assert doc['starts'] == 'multi'
    assert {x['start'] for x in doc['stances']} <= {'paper', 'stance1', 'stance2'}
    assert s['liftoff'] > s['touchdown']
    assert doc['gaits']['running']['stances'] == len(doc['stances'])
    # Eq. 2 read literally (world-frame bx) beside the origin-free nerr: per stance and gait
    world = [x['nerr_world'] for x in doc['stances']]
    assert all(w is not None and w > 0 for w in world)
    assert doc['gaits']['running']['nerr_world_mean'] == pytest.approx(np.mean(world))
    assert len(doc['failed_bags']) == 1 and 'lacks topic' in doc['failed_bags'][0]['error']
    # defaults: geometric edges and offset (the bag has hip angles), paper edges side by side
    r = doc['runs'][0]
    assert r['edges'] == 'geometry' and r['offset_method'] == 'geometry'
    assert r['frame']['ground_source'] == 'geometry' and r['ground_m'] is not None
    assert abs(r['offset_s'] - 0.025) <= 3e-3  # the simulator's default clock offset
    assert len(r['paper_edges']) >= 5 and len(r['geometry_edges']) >= 5
    geo_td = [e['touchdown'] for e in r['geometry_edges']]
    for s in doc['stances']:  # fitted from the geometric windows (stance samples at 1 kHz)
        assert min(abs(s['touchdown'] - t) for t in geo_td) <= 1e-3
    assert (out / 'fig9_nerr_vs_sr.png').is_file()


@pytest.mark.parametrize('mass', ['nan', '0', '-1', 'inf', 'heavy'])
def test_a_bad_mass_is_an_option_error(tmp_path, mass, capsys):
    """--mass nan, 0 or -1 was reported as every bag refused, exit 2, and slip.json was
    written with "mass_kg": NaN (not JSON); it is an option error now, before any bag."""
    parser = argparse.ArgumentParser(prog='hexapod-analyze')
    add_cli(parser.add_subparsers(dest='cmd'))
    with pytest.raises(SystemExit) as ex:
        parser.parse_args(['slip', str(tmp_path / 'no_bag'), '--out', str(tmp_path / 'o'),
                           f'--mass={mass}'])
    assert ex.value.code == 2
    assert '--mass' in capsys.readouterr().err
    assert not (tmp_path / 'o').exists()


def test_jobs_workers_report_the_messages_they_read(tmp_path):
    """`slip --jobs N` showed no per-message progress inside its workers (a long bag sat at
    0/N bags); each worker now counts what it reads to its parent's bar."""
    import queue

    from slip_identification.cli import _analyze_reporting, _message_total

    bag = edubot_sim.write_edubot_bag(tmp_path / 'run', 'running', duration_s=3.0, seed=1)
    q: queue.Queue = queue.Queue()
    out = _analyze_reporting(str(bag), {}, q)
    assert 'error' not in out
    counts = []
    while not q.empty():
        counts.append(q.get_nowait())
    assert sum(counts) == _message_total([str(bag)]) > 0


def test_ctrl_c_during_a_parallel_slip_is_an_interruption(tmp_path, monkeypatch, capsys):
    """Ctrl-C during ``slip --jobs 2`` exited 1 with 'failed: AttributeError ... please report
    it' (``pool.shutdown`` sets the pool's ``_processes`` to None before the workers were
    taken): an outside review. Now exit 130, 'interrupted'."""
    import slip_identification.cli as slip_cli
    from hexapod_common.analyze_cli import main

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(slip_cli, 'wait', interrupted)
    for name in ('a', 'b'):
        (tmp_path / name).mkdir()
    rc = main(['slip', str(tmp_path / 'a'), str(tmp_path / 'b'), '--out',
               str(tmp_path / 'out'), '--jobs', '2'])
    err = capsys.readouterr().err
    assert rc == 130 and 'interrupted' in err and 'AttributeError' not in err
