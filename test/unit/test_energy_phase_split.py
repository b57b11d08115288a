"""Phase powers normalised by the nominal phase time, and the bench-load offset of Eq. 1."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.prediction import predict_power_in_w
from hexapod_energy.single_leg import phase_powers
from hexapod_gait.gait import make_gait


def _session(contact_fraction: float):
    """4 cycles at 1 Hz, 100 Hz power: 3 W in contact, 9 W in the air; labels at 50 Hz."""
    t = np.arange(0, 4.0, 0.01)
    phase = t % 1.0
    power = np.where(phase < contact_fraction, 3.0, 9.0)
    tl = np.arange(0, 4.0, 0.02) + 0.001
    stance = (tl % 1.0) < contact_fraction
    return t, power, tl, stance


def test_nominal_normalisation_recombines_to_the_session_mean() -> None:
    t, p, tl, st = _session(0.7)
    s = phase_powers(t, p, tl, st, session_id='s', load_kg=0.1, frequency_hz=1.0,
                     duty_factor=0.5)
    assert s.stance_fraction == pytest.approx(0.7, abs=0.01)
    assert 0.5 * s.p_stance_w + 0.5 * s.p_swing_w == pytest.approx(p.mean(), rel=1e-12)
    assert s.p_stance_w == pytest.approx(np.mean(p * ((t % 1.0) < 0.7)) / 0.5, rel=0.02)
    plain = phase_powers(t, p, tl, st, session_id='s', load_kg=0.1, frequency_hz=1.0,
                         duty_factor=0.5, normalise='detected')
    assert plain.p_stance_w == pytest.approx(3.0) and plain.p_swing_w == pytest.approx(9.0)
    # plain means recombined with beta overstate the cycle: 6 W against 4.8 W
    assert 0.5 * plain.p_stance_w + 0.5 * plain.p_swing_w > 1.2 * p.mean()


def test_nominal_equals_detected_when_contact_matches_beta() -> None:
    t, p, tl, st = _session(0.5)
    kw = dict(session_id='s', load_kg=0.1, frequency_hz=1.0, duty_factor=0.5)
    a = phase_powers(t, p, tl, st, **kw)
    b = phase_powers(t, p, tl, st, normalise='detected', **kw)
    assert a.p_stance_w == pytest.approx(b.p_stance_w, rel=0.02)
    assert a.p_swing_w == pytest.approx(b.p_swing_w, rel=0.02)
    with pytest.raises(InvalidInputError, match='normalise'):
        phase_powers(t, p, tl, st, normalise='mean', **kw)


class Linear:
    def p_stance_w(self, t, m):
        return 2.0 + 4.0 * np.asarray(m) + 0 * np.asarray(t)

    def p_swing_w(self, t, m):
        return 3.0 + 0 * np.asarray(t) + 0 * np.asarray(m)


def test_load_offset_shifts_the_stance_load() -> None:
    gait = make_gait('tripod', period_s=1.0)
    total, leg = 2.183, 0.16601
    m_c = (total - 3 * leg) / 3
    paper = predict_power_in_w(Linear(), gait, total_mass_kg=total, leg_mass_kg=leg)
    net = predict_power_in_w(Linear(), gait, total_mass_kg=total, leg_mass_kg=leg,
                             load_offset_kg=leg)
    assert paper == pytest.approx(3 * (2 + 4 * m_c) + 3 * 3.0, rel=1e-12)
    assert paper - net == pytest.approx(3 * 4.0 * leg, rel=1e-12)


def test_power_in_a_label_gap_is_left_out_not_given_the_gaps_edge_label() -> None:
    """Labels (the force sensor or the tip tracking) missing for 1.4 s of a 4 s session: the
    power samples in the gap took the label of the nearest sample at its edge (a 1.5 s force
    gap on the simulated bench: stance fraction 0.71 -> 0.57, P_stance -18 %, silently); with
    ``max_label_gap_s`` they are left out."""
    t, p, tl, st = _session(0.5)
    keep = (tl < 1.2) | (tl >= 2.6)
    kw = dict(session_id='s', load_kg=0.1, frequency_hz=1.0, duty_factor=0.5,
              normalise='detected')
    bad = phase_powers(t, p, tl[keep], st[keep], **kw)
    good = phase_powers(t, p, tl[keep], st[keep], max_label_gap_s=0.1, **kw)
    assert good.p_stance_w == pytest.approx(3.0) and good.p_swing_w == pytest.approx(9.0)
    assert bad.p_stance_w > 3.5     # swing power labelled stance across the gap


def test_tip_samples_inside_a_force_gap_are_found() -> None:
    from hexapod_energy.bag_io import _far_from

    ref = np.concatenate([np.arange(0.0, 1.0, 0.01), np.arange(2.5, 4.0, 0.01)])
    t = np.array([-0.1, 0.5, 0.995, 1.5, 2.4, 2.505, 3.9, 4.2])
    assert _far_from(t, ref).tolist() == [True, False, True, True, True, False, False, True]
