"""World frame on simulated RHex-class runs with the default 3 deg mocap misalignment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slip_identification.pipeline import _up_from_quats
from slip_identification.preprocess import fit_world_frame

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


@pytest.mark.parametrize('gait,seed', [('running', 1), ('running', 2), ('jogging', 1)])
def test_misalignment_recovered_within_half_degree(gait, seed):
    run = edubot_sim.simulate_edubot(gait, duration_s=3.5, seed=seed)
    truth = run.truth['frame']
    rot = np.array(truth['mocap_from_ground_rotation'])  # columns: ground axes in mocap
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    normal_err = math.degrees(math.acos(np.clip(frame.rotation[2] @ rot[:, 2], -1, 1)))
    x_err = math.degrees(math.acos(np.clip(frame.rotation[0] @ rot[:, 0], -1, 1)))
    print(f'{gait} seed {seed}: ground normal error {normal_err:.3f} deg, '
          f'x axis error {x_err:.3f} deg')
    assert normal_err <= 0.5
    assert x_err <= 0.5
