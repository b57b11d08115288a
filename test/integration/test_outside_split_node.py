"""slip_fitter fed ``/joint_states`` split over one message per joint (another lab's driver).

A simulated EduBot run is published with each hip in its own JointState (right side first,
each stamped at its own read time, +-0.3 ms) and the commands split over two buses; every
message is spun until the node has taken it (arrival order as the core sees it). Before the
online assembler, the node dropped every message whose names were not the first one's and
published nothing. The fits must equal those of the core fed the same messages and number at
least 8.
"""

from __future__ import annotations

import numpy as np
import pytest

from slip_stream import assert_same_fits, core_fits, events, js_msg, mocap_msg, node_fits

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _messages(run):
    """(topic, msg) in arrival order: one JointState per hip, commands per 3-hip bus."""
    names = [f'{leg}_hip' for leg in run.leg_names]
    rng = np.random.default_rng(11)
    out = []
    for _, kind, i in events(run):
        if kind == 1:
            out.append(mocap_msg(run, i))
            continue
        t = float(run.t_s[i])
        for j in (3, 0, 4, 1, 5, 2):
            out.append(('js', js_msg([names[j]], t + float(rng.uniform(-3e-4, 3e-4)),
                                     run.hip_position_rad[i][[j]],
                                     run.hip_velocity_rad_s[i][[j]])))
        for g in ((0, 1, 2), (3, 4, 5)):
            out.append(('cmd', js_msg([names[j] for j in g], t, [],
                                      run.target_velocity_rad_s[i][list(g)])))
    return out


@pytest.mark.timeout(180)
def test_slip_fitter_publishes_fits_from_split_joint_states():
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    off = run.truth['clock_offset_s']
    msgs = _messages(run)
    core, expected = core_fits(msgs, off)
    assert core._joints.groups == 6 and len(expected) >= 8
    node, got = node_fits('slipsplit', msgs, off, len(expected))
    assert node['published'] == len(expected) == len(got)
    assert node['received'] == len(msgs)
    assert_same_fits(got, expected)
