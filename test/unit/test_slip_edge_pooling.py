"""Steady-state edges pooled over strides (geometry.leg_contacts(pool_steady=True)).

A leg that lands while the others carry the body sinks slowly, so a fraction of a millimetre
of mocap noise moves its gap's zero crossing by several milliseconds; in steady state the same
leg lands at the same phase every stride. Each edge is weighted by how sharply its own crossing
is determined: flat ones move toward the strides', sharp ones keep their own.
"""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification.geometry import fit_ground_offset, leg_contacts
from slip_sim_inputs import geometry_args

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _fitted(gait: str, seed: int):
    run = edubot_sim.simulate_edubot(gait, duration_s=4.5, seed=seed)
    args, pw, _ = geometry_args(run)
    fit = fit_ground_offset(*args, initial_offset_s=0.0, offset_range_s=0.06, x_m=pw[:, 0])
    return run, args, fit, pw[:, 0]


def _contacts(args, fit, x, **kw):
    return leg_contacts(*args, offset_s=fit.offset_s, ground_m=fit.ground_m, fit=fit, x_m=x,
                        **kw)[0]


def _touchdown_error_ms(run, leg: str, t: float) -> float:
    tr = np.array(run.truth['leg_contact'][leg])[:, 0]
    return 1e3 * float(t - tr[np.argmin(np.abs(tr - t))])


def test_late_touchdown_pooled_back():
    """Walk seed 2: R1 lands 8.8 ms late at its third touchdown (0.05 mm of sinking in 5 ms
    while the other legs carry the body); pooled, within 5 ms, and the leg's other edges stay
    within 2 ms of the truth."""
    run, args, fit, x = _fitted('walk', 2)
    info: dict = {}
    raw = _contacts(args, fit, x, pool_steady=False)
    pooled = _contacts(args, fit, x, info=info)
    late = raw['R1'][2, 0]
    assert _touchdown_error_ms(run, 'R1', late) > 5.0
    assert abs(_touchdown_error_ms(run, 'R1', pooled['R1'][2, 0])) < 2.0
    for t in pooled['R1'][:, 0]:
        assert abs(_touchdown_error_ms(run, 'R1', t)) < 2.0
    assert info['pooled_edges'] > 20 and info['pooled_max_move_s'] > 5e-3
    # the same number of contacts, each still an interval
    for leg in raw:
        assert pooled[leg].shape == raw[leg].shape
        assert np.all(pooled[leg][:, 1] > pooled[leg][:, 0])


def test_sharp_edges_keep_their_own():
    """Running: legs land under load (fast crossings), so pooling moves no edge by more
    than a millisecond."""
    run, args, fit, x = _fitted('running', 1)
    info: dict = {}
    raw = _contacts(args, fit, x, pool_steady=False)
    pooled = _contacts(args, fit, x, info=info)
    assert info['pooled_edges'] > 20
    assert info['pooled_max_move_s'] < 1e-3
    for leg in raw:
        assert np.max(np.abs(pooled[leg] - raw[leg])) < 1e-3


def test_no_pooling_without_fit_or_when_off():
    """Pooling needs the fit (its residual RMS is the height error); off, nothing moves."""
    run, args, fit, x = _fitted('walk', 2)
    info: dict = {}
    a = _contacts(args, fit, x, pool_steady=False, info=info)
    assert info == {}
    b = leg_contacts(*args, offset_s=fit.offset_s, ground_m=fit.ground_m, x_m=x,
                     tilt_rad=fit.tilt_rad, info=info)[0]
    assert info == {}
    assert set(a) == set(b)
