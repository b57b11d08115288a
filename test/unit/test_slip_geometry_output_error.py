"""Output-error refinement of the geometric ground and offset fit (geometry.py, refine='output').

The equation-error fit takes each leg's penetration from the measured (noisy) height, which
biases its ground low on simulated pace (errors in variables); the output-error fit simulates
the height and takes the penetrations from the simulation, so the noise enters the target only.
"""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification.errors import SlipDataError
from slip_identification.geometry import (
    LegGeometry,
    _Body,
    _OutputError,
    _windows,
    body_pitch_rad,
    fit_ground_offset,
)
from slip_identification.pipeline import _up_from_quats
from slip_identification.preprocess import fit_world_frame

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _inputs(run):
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    pw = frame.to_world(run.mocap_position_m)
    pitch = body_pitch_rad(frame.rotation, run.mocap_quat_xyzw)
    off = run.truth['clock_offset_s']
    ground = float(np.mean(pw[:, 2] - np.interp(run.mocap_t_s - off, run.fine_t_s,
                                                 run.fine_state[:, 2])))
    geo = LegGeometry.from_params(run.params)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    args = (geo, names, run.t_s, run.hip_position_rad, run.hip_velocity_rad_s, run.mocap_t_s,
            pw[:, 2], pitch)
    return args, pw[:, 0], ground, off


@pytest.fixture(scope='module')
def pace_runs():
    return edubot_sim.simulate_edubot_batch('pace', duration_s=4.5, seeds=(1, 5))


def test_output_error_ground_unbiased_on_simulated_pace(pace_runs):
    """Pace seeds 1 and 5 (0.2 mm mocap noise): the equation-error ground is 0.29 / 0.33 mm
    low, the output-error one -0.05 / +0.13 mm off; offsets within 1 ms either way."""
    for run in pace_runs:
        args, x, ground, off = _inputs(run)
        eq = fit_ground_offset(*args, initial_offset_s=0.0, offset_range_s=0.06, x_m=x,
                               refine='none')
        oe = fit_ground_offset(*args, initial_offset_s=0.0, offset_range_s=0.06, x_m=x)
        e_eq, e_oe = 1e3 * (eq.ground_m - ground), 1e3 * (oe.ground_m - ground)
        print(f'pace seed {run.seed}: ground equation error {e_eq:+.2f} mm, output error '
              f'{e_oe:+.2f} mm; offset {1e3 * (eq.offset_s - off):+.2f} / '
              f'{1e3 * (oe.offset_s - off):+.2f} ms; {eq.windows} / {oe.windows} windows')
        assert e_eq < -0.2, (run.seed, e_eq)  # the bias the refinement removes
        assert abs(e_oe) < 0.2, (run.seed, e_oe)
        assert abs(oe.offset_s - off) < 1e-3
        # the simulated height is what leg_contacts uses: finite in the windows, near the data
        assert np.isfinite(oe.height_m).sum() > 0.5 * oe.height_m.size
        assert oe.rms_m < 3e-4


def test_output_error_sensitivities_match_finite_differences(pace_runs):
    """The window parameters' Jacobian (the simulation's exact sensitivities) against finite
    differences, on one simulated run."""
    args, x, ground, off = _inputs(pace_runs[0])
    body = _Body(*args, x_m=x)
    masks = [m for m in _windows(body.tm, 0.2)[2:8]]
    tf = np.arange(body.tm[0] + 0.05, body.tm[-1] - 0.05, 1e-3) - off
    oe = _OutputError(body, masks, tf, 0.0034, off, 5e-3)
    n = oe.n_w
    rng = np.random.default_rng(0)
    k = np.full(n, 1.2e3) * (1 + 0.1 * rng.standard_normal(n))
    h0 = 0.101 + 0.002 * rng.standard_normal(n)
    v0 = 0.02 * rng.standard_normal(n)
    r, sr = oe.residual(off, ground, 0.0, 0.0, k, h0, v0, sens=True)
    assert sr.shape == (3, r.size)
    for p, step in enumerate((1e-2, 1e-8, 1e-6)):
        for w in (0, n - 1):
            args_p = [k.copy(), h0.copy(), v0.copy()]
            args_p[p][w] += step
            rp = oe.residual(off, ground, 0.0, 0.0, *args_p)
            fd = (rp - r) / step
            np.testing.assert_allclose(sr[p], np.where(oe.win == w, fd, sr[p]), rtol=0,
                                       atol=1e-3 * np.max(np.abs(fd)) + 1e-12)
            # only the window's own samples depend on its parameters
            assert np.all(fd[oe.win != w] == 0.0)


def test_refine_modes_validated(pace_runs):
    args, x, *_ = _inputs(pace_runs[0])
    with pytest.raises(SlipDataError, match='refine'):
        fit_ground_offset(*args, x_m=x, refine='simex')
    with pytest.raises(SlipDataError, match='clipped'):
        fit_ground_offset(*args, x_m=x, model='linear', refine='output')
