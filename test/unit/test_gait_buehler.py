"""Buehler clock for RHex-class legs (issue 3, item 5; Komsuoglu et al. Table 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import quad

from hexapod_gait.buehler import BUEHLER_PRESETS, TRIPOD_LEGS, BuehlerClock, tripod_of_leg
from hexapod_gait.errors import InvalidGaitError


@pytest.mark.parametrize('name', sorted(BUEHLER_PRESETS))
@pytest.mark.parametrize('tripod', ['left', 'right'])
def test_target_speed_integrates_to_one_turn_per_cycle(name, tripod):
    clock = BUEHLER_PRESETS[name]
    T, dc = clock.period_s, clock.duty_factor
    t0 = 0.123 * T  # any cycle start
    shift = 0.0 if tripod == 'left' else 0.5 * T
    switches = [shift + T * (k + f) for k in range(-2, 3) for f in (0.0, dc)]
    breaks = sorted(x for x in switches if t0 < x < t0 + T)
    assert len(breaks) == 2
    turn, _ = quad(lambda t: clock.target_speed(t, tripod)[0], t0, t0 + T,
                   points=breaks, limit=200, epsabs=1e-12)
    assert_allclose(turn, 2 * math.pi, rtol=1e-9)
    angle = clock.target_angle([t0, t0 + T], tripod)
    assert_allclose(angle[1] - angle[0], 2 * math.pi, rtol=1e-12)


def test_table1_presets():
    expected = {  # w_c, phi_s, phi_0, dc
        'running': (19.0, 0.75, 0.35, 0.3), 'jogging': (17.4, 1.12, 0.2, 0.45),
        'pace': (10.0, 1.0, 0.2, 0.6), 'walk': (6.0, 1.2, 0.0, 0.7),
    }
    for name, (wc, phs, ph0, dc) in expected.items():
        c = BUEHLER_PRESETS[name]
        assert_allclose(c.period_s, 2 * math.pi / wc)
        assert (c.sweep_angle_rad, c.leg_offset_rad, c.duty_factor) == (phs, ph0, dc)
    # the paper: the running gait's stance interval is about 100 ms
    assert abs(BUEHLER_PRESETS['running'].duty_factor * BUEHLER_PRESETS['running'].period_s
               - 0.1) < 0.002


def test_two_speed_profile_shape():
    c = BuehlerClock(period_s=1.0, duty_factor=0.6, sweep_angle_rad=1.0, leg_offset_rad=0.2)
    t = np.linspace(0, 3, 30001)
    a = c.target_angle(t, 'left')
    assert np.all(np.diff(a) > 0)  # unwrapped, monotonic
    speed = c.target_speed(t, 'left')
    slow = c.in_slow_phase(t, 'left')
    assert_allclose(speed[slow], 1.0 / 0.6)
    assert_allclose(speed[~slow], (2 * math.pi - 1.0) / 0.4)
    # slow phase centred on the leg offset: from phi0 - phi_s/2 to phi0 + phi_s/2
    assert_allclose(c.target_angle([0.0, 0.6], 'left'), [0.2 - 0.5, 0.2 + 0.5])
    # right tripod half a period later
    assert_allclose(c.target_angle(t[:1000] + 0.5, 'right'), c.target_angle(t[:1000], 'left'))
    # continuity of the angle at the phase boundaries
    for tb in (0.6, 1.0, 1.6):
        jump = np.diff(c.target_angle([tb - 1e-12, tb + 1e-12], 'left'))[0]
        assert abs(jump) < 1e-10


def test_stance_windows():
    c = BUEHLER_PRESETS['walk']
    T = c.period_s
    w = c.stance_windows(0.0, 3.1 * T, 'right')
    assert_allclose(w, [[(k + 0.5) * T, (k + 0.5 + 0.7) * T] for k in range(2)])
    wc = c.stance_windows(0.0, 3.1 * T, 'right', clip=True)
    assert_allclose(wc[0], [0.0, 0.2 * T], atol=1e-15)
    assert_allclose(wc[-1], [2.5 * T, 3.1 * T])
    mid = w.mean(axis=1)
    assert np.all(c.in_slow_phase(mid, 'right'))


def test_tripods_and_pattern():
    assert [tripod_of_leg(leg) for leg in TRIPOD_LEGS['left']] == ['left'] * 3
    assert [tripod_of_leg(leg) for leg in TRIPOD_LEGS['right']] == ['right'] * 3
    p = BUEHLER_PRESETS['pace'].as_pattern()
    assert p.name == 'buehler' and p.duty_factor == 0.6
    assert dict(zip(p.leg_names, p.phase_offsets))['R2'] == 0.0
    assert p.min_supporting_legs() == 3 and p.max_supporting_legs() == 6


def test_invalid_clock_is_refused():
    with pytest.raises(InvalidGaitError, match='sweep_angle_rad'):
        BuehlerClock(period_s=1.0, duty_factor=0.5, sweep_angle_rad=7.0)
    with pytest.raises(InvalidGaitError, match='tripod'):
        BUEHLER_PRESETS['walk'].target_angle(0.0, 'middle')
