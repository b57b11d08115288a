"""Shared by the slip geometry tests: the geometric fit's inputs from a simulated EduBot run
(the steps analyze_run takes before fit_ground_offset: world frame from the mocap path and
attitude, heights and pitch in it)."""

from __future__ import annotations

from typing import Any

import numpy as np

from slip_identification.geometry import LegGeometry, body_pitch_rad
from slip_identification.pipeline import _up_from_quats
from slip_identification.preprocess import WorldFrame, fit_world_frame


def geometry_args(run: Any) -> tuple[tuple[Any, ...], np.ndarray, WorldFrame]:
    """(fit_ground_offset's positional arguments, mocap positions in the world frame, the
    frame)."""
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    pw = frame.to_world(run.mocap_position_m)
    pitch = body_pitch_rad(frame.rotation, run.mocap_quat_xyzw)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    args = (LegGeometry.from_params(run.params), names, run.t_s, run.hip_position_rad,
            run.hip_velocity_rad_s, run.mocap_t_s, pw[:, 2], pitch)
    return args, pw, frame
