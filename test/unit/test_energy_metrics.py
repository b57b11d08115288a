"""Descriptors of DESIGN §4; Komsuoglu et al. Table 3 specific resistance."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_energy import metrics

# Komsuoglu et al., Table 3: mean power [W], mean speed [m/s]; Sec. 5 reports SR.
TABLE3 = {
    'running': (31.63, 1.06, 0.92),
    'jogging': (42.92, 0.64, 2.07),
    'pace': (26.23, 0.30, 2.69),
    'walk': (20.93, 0.16, 4.03),
}
EDUBOT_MASS_KG = 3.31


@pytest.mark.parametrize('gait', sorted(TABLE3))
def test_specific_resistance_table3(gait: str) -> None:
    power_w, speed_mps, expected = TABLE3[gait]
    sr = metrics.specific_resistance(power_w, EDUBOT_MASS_KG, speed_mps)
    assert abs(sr - expected) <= 0.01


def test_descriptors_definitions() -> None:
    d = metrics.descriptors(power_in_w=40.0, power_out_w=1.0, mass_kg=2.0, speed_mps=0.5)
    assert d.power_loss_w == 39.0
    assert_allclose(d.efficiency, 1.0 / 40.0)
    assert_allclose(d.cost_of_transport_j_per_m, 78.0)
    assert_allclose(d.specific_cost_of_transport_j_per_m_kg, 39.0)
    assert_allclose(d.specific_resistance, 40.0 / (2.0 * 9.81 * 0.5))


def test_vectorised_and_zero_speed() -> None:
    cot = metrics.specific_cost_of_transport([10.0, 10.0], [0.0, 2.0], 2.0, [0.0, 0.4])
    assert np.isinf(cot[0])
    assert_allclose(cot[1], 10.0)
