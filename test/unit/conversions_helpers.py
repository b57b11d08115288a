"""Small sample builders shared by the energy core tests."""

from __future__ import annotations

import numpy as np

from hexapod_common.conversions import JointStateSample


def joint_sample(t_s: float, power_w: float) -> JointStateSample:
    """One joint doing ``power_w`` of positive work (effort 1 N m at ``power_w`` rad/s)."""
    return JointStateSample(t_s, ('L1_coxa',), np.zeros(1), np.array([power_w]), np.ones(1))
