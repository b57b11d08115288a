"""Hip angles wrapped by the driver ((-pi, pi] or [0, 2 pi)) through the geometry API: the same
fit and contacts as continuous ones (the bag readers unwrap, but RunData and the geometry
functions are public; the hip spline through a wrap swung a whole turn between two samples
and made contacts that are not there: walk 0 of 15 stances, silently; outside review)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slip_identification.geometry import fit_ground_offset, leg_contacts, unwrap_with_speed
from slip_sim_inputs import geometry_args

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def test_unwrap_with_speed():
    t = np.linspace(0.0, 2.0, 201)
    q = np.stack([6.0 * t, -6.0 * t, 0.3 * np.sin(3 * t)], axis=1)
    v = np.stack([np.full_like(t, 6.0), np.full_like(t, -6.0), 0.9 * np.cos(3 * t)], axis=1)
    wrapped = np.angle(np.exp(1j * q))
    assert np.allclose(unwrap_with_speed(t, wrapped, v) - wrapped[0] + q[0], q)
    assert unwrap_with_speed(t, q, v) is q  # continuous: unchanged
    # a sampling gap longer than half a turn: the speeds carry the turns across it
    keep = (t < 0.5) | (t > 0.9)
    got = unwrap_with_speed(t[keep], wrapped[keep], v[keep])
    assert np.allclose(got - got[0] + q[0], q[keep])


@pytest.mark.parametrize('wrap', ['pi', '2pi'])
def test_wrapped_hips_give_the_same_contacts(wrap):
    run = edubot_sim.simulate_edubot('walk', duration_s=4.5, seed=1)
    args, pw, _ = geometry_args(run)
    q = args[3]
    wrapped = np.angle(np.exp(1j * q)) if wrap == 'pi' else np.mod(q, 2 * math.pi)
    assert np.max(np.abs(np.diff(wrapped, axis=0))) > 6.0  # it does wrap
    out = []
    for a in (args, args[:3] + (wrapped,) + args[4:]):
        fit = fit_ground_offset(*a, initial_offset_s=0.0, offset_range_s=0.06, x_m=pw[:, 0])
        c, _ = leg_contacts(*a, offset_s=fit.offset_s, ground_m=fit.ground_m, fit=fit,
                            x_m=pw[:, 0])
        out.append((fit.offset_s, c))
    assert out[1][0] == pytest.approx(out[0][0], abs=1e-9)
    for leg, iv in out[0][1].items():
        assert iv.shape == out[1][1][leg].shape
        assert np.allclose(iv, out[1][1][leg], atol=1e-9)
