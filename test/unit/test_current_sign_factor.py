"""``current_sign_factor('auto')`` decides by the median of V * I, so a few regenerative or
glitch samples do not decide it (a mutation review: a mean passed the suite)."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.conversions import current_sign_factor


def test_auto_sign_is_decided_by_most_samples_not_by_spikes():
    v = np.full(105, 12.0)
    i = np.full(105, -1.0)          # discharging at 1 A, ROS convention
    i[::21] = 500.0                 # five glitches of +500 A outweigh the mean
    assert np.mean(v * i) > 0
    assert current_sign_factor(v, i, 'auto') == -1.0
    assert current_sign_factor(v, -i, 'auto') == 1.0


def test_fixed_modes_and_a_bad_mode():
    assert current_sign_factor([12.0], [1.0], 'ros') == -1.0
    assert current_sign_factor([12.0], [-1.0], 'positive_discharge') == 1.0
    with pytest.raises(ValueError, match='current sign'):
        current_sign_factor([12.0], [1.0], 'negative')
