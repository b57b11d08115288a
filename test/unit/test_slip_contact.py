"""Edges refined from the ballistic body height (contact.py) on a noise-free simulated run."""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification.contact import refine_contact_edges

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


@pytest.mark.parametrize('seed', [1, 2, 3, 4])
def test_touchdown_from_body_height_noise_free(seed):
    run = edubot_sim.simulate_edubot('running', duration_s=3.0, seed=seed,
                                     effects={'mocap_noise': 0.0})
    c = np.concatenate([np.array(run.truth['tripod_contact'][tp]) for tp in ('left', 'right')])
    c = c[np.argsort(c[:, 0])]
    c = c[(c[:, 0] > 1.6) & (c[:, 1] < 2.9)]
    start = np.random.default_rng(0).uniform(-0.015, 0.015, c.shape)  # rough initial edges
    got, rms = refine_contact_edges(run.fine_t_s, run.fine_state[:, 2], c + start)
    err_ms = 1e3 * (got - c)
    # the method needs a flight phase on both sides of a stance (module docstring); early in
    # a run some stances abut their neighbours
    flight = np.diff(c.ravel())[1::2] > 0.005
    aerial = np.concatenate([[True], flight]) & np.concatenate([flight, [True]])
    assert aerial.sum() >= 5
    err_ms = err_ms[aerial]
    print(f'touchdown error {err_ms[:, 0].mean():.2f} +- {err_ms[:, 0].std():.2f} ms; '
          f'force-zero lift-off minus geometric lift-off {err_ms[:, 1].mean():.1f} +- '
          f'{err_ms[:, 1].std():.1f} ms')
    # With the rolling C-leg the three legs of a tripod land over 2-35 ms (first-leg force
    # about a quarter of mid-stance) and the first stances of a run abut without flight, so the
    # single-jump polynomial force model is off by up to 4 ms on some stances (was within 1 ms
    # for the pinned-foot simulator; that 1 ms / 90 % bar was tuned to it, not the issue's).
    # Bars now: median within 1 ms (bias), every stance within the 5 ms.
    assert np.median(np.abs(err_ms[:, 0])) <= 1.0
    assert np.all(np.abs(err_ms[:, 0]) <= 5.0)
    assert np.all(np.isfinite(rms))
    # the vertical force vanishes before the simulator's geometric lift-off (spoke back at
    # rest length): lift-off from body motion is early, never late
    assert np.all(err_ms[:, 1] < 1.0)
