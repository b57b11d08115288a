"""``slip_fitter`` on a RHex whose right-side hip motors are mounted mirrored: their angles,
speeds and commands arrive negated. With ``hip_signs:=[1, 1, 1, -1, -1, -1]`` (the value the
offline analysis prints when it detects it) the node publishes the fits of the unmirrored run."""

from __future__ import annotations

import pytest
from rclpy.parameter import Parameter

from slip_stream import assert_same_fits, core_fits, events, js_msg, mocap_msg, node_fits

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _messages(run, sign):
    names = [f'{leg}_hip' for leg in run.leg_names]
    k = [sign if n.startswith('R') else 1.0 for n in names]
    out = []
    for _, kind, i in events(run):
        if kind == 1:
            out.append(mocap_msg(run, i))
            continue
        t = float(run.t_s[i])
        out.append(('js', js_msg(names, t, k * run.hip_position_rad[i],
                                 k * run.hip_velocity_rad_s[i])))
        out.append(('cmd', js_msg(names, t, k * run.target_position_rad[i],
                                  k * run.target_velocity_rad_s[i])))
    return out


@pytest.mark.timeout(180)
def test_mirrored_right_hips_with_hip_signs():
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    off = run.truth['clock_offset_s']
    _, expected = core_fits(_messages(run, 1.0), off)
    assert len(expected) >= 8
    mirrored = _messages(run, -1.0)
    node, got = node_fits('hipsigns', mirrored, off, len(expected), params=(
        Parameter('hip_signs', value=[1.0, 1.0, 1.0, -1.0, -1.0, -1.0]),))
    assert node['published'] == len(expected)
    assert_same_fits(got, expected)
