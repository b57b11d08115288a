"""slip_fitter fed another lab's joint states: hip angles wrapped into [-pi, pi), no velocities.

A simulated EduBot run is published with ``/joint_states`` carrying wrapped positions and an
empty velocity array (commands as the gait node sends them); every message is spun until the
node has taken it. Before ``JointFrameAssembler`` derived the speeds, every such message was
dropped ('has 0 velocities') and nothing was published. The fits must equal those of the core
fed the same messages (at least 8), the core must report both fallbacks, and the stances must
be those of the run with the simulator's velocities and unwrapped angles (same count, edges
within 2.5 ms: the paper's edges move by ~1.5 ms with central-difference speeds).
"""

from __future__ import annotations

import math

import pytest

from slip_stream import assert_same_fits, core_fits, events, js_msg, mocap_msg, node_fits

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _messages(run, *, wrapped_no_velocity: bool):
    names = [f'{leg}_hip' for leg in run.leg_names]
    out = []
    for _, kind, i in events(run):
        if kind == 1:
            out.append(mocap_msg(run, i))
            continue
        t = float(run.t_s[i])
        q = run.hip_position_rad[i]
        if wrapped_no_velocity:
            out.append(('js', js_msg(names, t, (q + math.pi) % (2 * math.pi) - math.pi, [])))
        else:
            out.append(('js', js_msg(names, t, q, run.hip_velocity_rad_s[i])))
        out.append(('cmd', js_msg(names, t, run.target_position_rad[i],
                                  run.target_velocity_rad_s[i])))
    return out


@pytest.mark.timeout(180)
def test_slip_fitter_publishes_fits_from_wrapped_velocity_less_joint_states():
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    off = run.truth['clock_offset_s']
    msgs = _messages(run, wrapped_no_velocity=True)
    core, expected = core_fits(msgs, off)
    assert len(expected) >= 8 and core._joints.derived and core._joints.wraps > 20
    assert [n.split(':')[0] for n in core.notes] == [
        'no joint velocities', 'hip angles wrapped (jumps of 2 pi between samples)']
    _, ref = core_fits(_messages(run, wrapped_no_velocity=False), off)
    assert len(ref) == len(expected)
    for a, b in zip(ref, expected):
        assert a.tripod == b.tripod
        assert abs(a.touchdown_s - b.touchdown_s) <= 2.5e-3
        assert abs(a.liftoff_s - b.liftoff_s) <= 2.5e-3

    node, got = node_fits('slipwrap', msgs, off, len(expected))
    assert node['published'] == len(expected) == len(got)
    assert node['received'] == len(msgs)
    assert node['notes_logged'] == 2  # each fallback logged once
    assert_same_fits(got, expected)
