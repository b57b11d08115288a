"""The geometric fit's fast paths against the straightforward ones: the output-error
simulation compiled (numba) against its numpy loop (same heights, velocities and
sensitivities on windows in contact, in flight and past the grid's end; the whole ground and
offset fit the same either way); the tilted height's and shifted pitch's splines combined from
splines of the data against splines built on the tilted data (also with the tilt's reference
x moved after construction, as leg_contacts does); the cached gaps against fresh ones."""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification import geometry
from slip_identification._geometry_kernels import HAVE_NUMBA

pytestmark = pytest.mark.skipif(not HAVE_NUMBA, reason='numba not installed')


class _Stub(geometry._OutputError):
    """The simulation alone: grid indices and sizes without a body."""

    def __init__(self, i0, n_steps, n_grid, tau, step):  # noqa: D107
        self.i0 = np.asarray(i0)
        self.n_steps = n_steps
        self.n_w = self.i0.size
        self.tau, self.step = tau, step
        self.grid_i = np.minimum(self.i0[None, :] + np.arange(n_steps)[:, None], n_grid - 1)


def _both(monkeypatch, oe, *args, sens):
    monkeypatch.setattr(geometry, 'COMPILED_SIMULATION', False)
    ref = oe.simulate(*args, sens=sens)
    monkeypatch.setattr(geometry, 'COMPILED_SIMULATION', True)
    return ref, oe.simulate(*args, sens=sens)


@pytest.mark.parametrize('sens', [False, True])
def test_compiled_simulation_matches_the_numpy_loop(monkeypatch, sens) -> None:
    rng = np.random.default_rng(3)
    n_grid, n_leg, step = 900, 6, 1e-3
    t = np.arange(n_grid) * step
    # legs' reach oscillating about the start height: contacts switch on and off
    q = 0.1 + 0.004 * np.sin(2 * np.pi * 3 * t[:, None] + rng.uniform(0, 6, n_leg))
    qd = np.gradient(q, step, axis=0)
    i0 = np.array([0, 150, 400, 820])          # the last runs past the grid's end
    oe = _Stub(i0, 200, n_grid, tau=0.01, step=step)
    k = np.array([900.0, 1500.0, 0.0, 1200.0])  # one window without stiffness: ballistic
    h0 = np.array([0.1, 0.098, 0.12, 0.101])
    v0 = np.array([0.0, 0.05, -0.1, 0.02])
    ref, out = _both(monkeypatch, oe, q, qd, k, h0, v0, sens=sens)
    assert len(ref) == len(out) == (4 if sens else 2)
    for a, b in zip(ref, out):
        assert a.shape == b.shape
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14)
    # the case exercises contact and flight
    hh = out[0]
    assert np.any(q[np.minimum(i0 + 50, n_grid - 1)] > hh[50][:, None])
    assert np.any(np.all(q[np.minimum(i0 + 50, n_grid - 1)] < hh[50][:, None], axis=1))


@pytest.fixture(scope='module')
def pace_args():
    edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from slip_identification.pipeline import _up_from_quats
    from slip_identification.preprocess import fit_world_frame

    run = edubot_sim.simulate_edubot_batch('pace', duration_s=2.5, seeds=(1,))[0]
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    pw = frame.to_world(run.mocap_position_m)
    pitch = geometry.body_pitch_rad(frame.rotation, run.mocap_quat_xyzw)
    geo = geometry.LegGeometry.from_params(run.params)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    args = (geo, names, run.t_s, run.hip_position_rad, run.hip_velocity_rad_s, run.mocap_t_s,
            pw[:, 2], pitch)
    # the lab's origin far from the run (x about 2.4 m): the tilt's reference x matters
    return args, pw[:, 0] + 2.4


def test_tilted_splines_and_cached_gaps(pace_args) -> None:
    from scipy.interpolate import CubicSpline

    args, x = pace_args
    body = geometry._Body(*args, x_m=x)
    tt = np.linspace(body.tm[0] - 0.01, body.tm[-1] + 0.01, 2001)   # extrapolated ends too
    tf = np.arange(body.tm[0] + 0.05, body.tm[-1] - 0.05, 1e-3)
    for x0 in (None, 1.0):
        if x0 is not None:
            body.x0 = x0
        for tilt, p0 in ((0.003, 0.0), (-0.002, 0.05), (0.0, -0.01)):
            body.set_tilt(tilt, p0)
            z = body.z_raw - tilt * (body.x - body.x0)
            np.testing.assert_allclose(body.zs(tt), CubicSpline(body.tm, z)(tt), atol=1e-12)
            b = CubicSpline(body.tm, body.b_raw + tilt + p0)
            np.testing.assert_allclose(body.bs(tt), b(tt), atol=1e-12)
            for d, g in ((0.0, 0.0), (0.003, 0.01), (0.003, -0.02)):
                cached = body.gaps(tf, d, g)
                body._gap_key = None
                np.testing.assert_allclose(cached, body.gaps(tf, d, g), atol=1e-12)


def test_fit_same_with_the_compiled_simulation(monkeypatch, pace_args) -> None:
    args, x = pace_args
    kw = dict(initial_offset_s=0.0, offset_range_s=0.06, x_m=x, fit_pitch_offset=False)
    fits = []
    for compiled in (False, True):
        monkeypatch.setattr(geometry, 'COMPILED_SIMULATION', compiled)
        fits.append(geometry.fit_ground_offset(*args, **kw))
    a, b = fits
    assert b.offset_s == pytest.approx(a.offset_s, abs=1e-9)
    assert b.ground_m == pytest.approx(a.ground_m, abs=1e-9)


def test_compiled_cost_matches_the_numpy_cost(monkeypatch, pace_args) -> None:
    """The equation-error cost's scalar path compiled against the numpy code: both models,
    two window lists, grounds from far below the legs (no contact: every window's 2 x 2
    system singular, the pseudo-inverse) to deep contact, offsets, tilts, damping times."""
    args, x = pace_args
    body = geometry._Body(*args, x_m=x)
    tf = np.arange(body.tm[0] + 0.05, body.tm[-1] - 0.05, 1e-3)
    fixed = geometry._windows(body.tm, 0.1)
    inside = (body.tm > tf[0] + 0.03) & (body.tm < tf[-1] - 0.03)
    fixed = [k & inside for k in fixed if np.sum(k & inside) >= 8]
    flight = geometry._flight_windows(body, tf[0] + 0.03, tf[-1] - 0.03, 0.0, 0.0)
    assert len(fixed) >= 6
    n_cases = 0
    for masks in (fixed, fixed[::2], flight) if len(flight) >= 3 else (fixed, fixed[::2]):
        for tilt, p0 in ((0.0, 0.0), (0.002, -0.01)):
            body.set_tilt(tilt, p0)
            for d in (-0.004, 0.0, 0.0071):
                for g in (-0.5, 0.0, 0.015, 0.02, 0.025, 0.03):
                    for model, tau in (('clipped', 0.0034), ('clipped', 0.0),
                                       ('linear', 0.0)):
                        out = []
                        for compiled in (False, True):
                            monkeypatch.setattr(geometry, 'COMPILED_COST', compiled)
                            out.append(geometry._cost(body, masks, tf, d, g, model=model,
                                                      tau_s=tau))
                        ref, got = out
                        assert np.isfinite(ref) and ref >= 0.0
                        # both solve normal equations: with the legs in contact each is
                        # about 1e-10 (relative) from a least-squares solve of the windows;
                        # at a ground where the legs barely touch (0.015 m) the contact term
                        # is nearly collinear with the free ones and both are 1e-7 to 1e-4
                        # from it
                        rel = 5e-9 if g >= 0.02 else 3e-4
                        assert got == pytest.approx(ref, rel=rel, abs=1e-18)
                        n_cases += 1
    assert n_cases >= 216


def test_compiled_gaps_match_the_numpy_gaps(monkeypatch, pace_args) -> None:
    """The legs' gaps compiled against the numpy code (rest height of toe and rolling
    contact, a leg pointing up, samples outside the motion capture's span: +inf)."""
    args, x = pace_args
    body = geometry._Body(*args, x_m=x)
    tf = np.arange(body.tm[0] - 0.02, body.tm[-1] + 0.02, 1e-3)
    for tilt, p0, d in ((0.0, 0.0, 0.0), (0.002, -0.01, 0.004), (0.0, 2.0, -0.003)):
        body.set_tilt(tilt, p0)
        out = []
        for compiled in (False, True):
            monkeypatch.setattr(geometry, 'COMPILED_COST', compiled)
            body._gap_key = None
            out.append(body.gaps(tf, d, 0.01).copy())
        ref, got = out
        assert np.isinf(ref[0]).all() and np.isinf(ref[-1]).all()
        np.testing.assert_array_equal(np.isinf(got), np.isinf(ref))
        fin = np.isfinite(ref)
        np.testing.assert_allclose(got[fin], ref[fin], rtol=0, atol=1e-14)
    # the three branches of the rest height occur
    assert np.any(ref[fin] > 0.5)     # a leg pointing up: rest height -1 m
