"""``hexapod_common.series.robust_sigma``: the one robust spread the analyses share."""

import numpy as np
import pytest
from scipy.stats import median_abs_deviation

from hexapod_common.series import MAD_TO_SIGMA, robust_sigma


def test_equals_scaled_mad_about_the_median():
    x = np.random.default_rng(3).normal(2.0, 0.5, 4001)
    mad = median_abs_deviation(x)
    assert robust_sigma(x) == pytest.approx(MAD_TO_SIGMA * mad, rel=1e-15)
    assert robust_sigma(x) == pytest.approx(0.5, rel=0.05)


def test_an_outlier_moves_it_no_more_than_any_sample():
    x = np.random.default_rng(4).normal(0.0, 1.0, 1001)
    y = x.copy()
    y[0] = 1e6
    z = x.copy()
    z[0] = x[0] + 3.0
    assert abs(robust_sigma(y) - robust_sigma(x)) <= abs(robust_sigma(z) - robust_sigma(x)) + 0.01


def test_given_centre_and_deviations():
    x = np.array([1.0, 2.0, 4.0, 8.0])
    assert robust_sigma(x, 0.0) == MAD_TO_SIGMA * 3.0  # median of |x| = (2 + 4) / 2
    assert robust_sigma(x) == MAD_TO_SIGMA * 1.5  # median 3; |x - 3| = 2, 1, 1, 5


def test_empty_is_refused():
    with pytest.raises(ValueError, match='at least one'):
        robust_sigma([])
