"""Findings of an outside review of `hexapod-analyze slip` on its own RHex-class runner
(its own simulator: 8 kg, undamped 0.17 m legs, 0.13 s stances).

- A given stream offset (``--offset``) left EduBot's assumed leg damping time (3.4 ms)
  unchecked: the fit made up for it with a spurious rigid-body pitch zero (-2.44 deg there,
  -3.37 deg on LabHex here) and the edges were 8-16 ms off. The assumed damping is now checked
  against undamped legs at the given offset too.
- Hip efforts that rise slowly (undamped legs, long stances) cross the onset threshold (15 %
  of their range) late: the geometric touchdowns came 6.1-6.4 ms before the onsets and a
  warning said the leg description did not fit the robot, on exact geometry. The tolerance
  now adds how late the threshold is crossed (``effort_onset_rise_s``).
"""

from __future__ import annotations

import types

import numpy as np

from slip_identification.geometry import LegGeometry
from slip_identification.pipeline import RunResult, _effort_contact_check

from test_slip_review_cases import LABHEX, _edge_errors_ms, _labhex

LEGS = ('L1', 'R2', 'L3', 'R1', 'L2', 'R3')


def test_a_given_offset_checks_the_assumed_damping_against_undamped_legs(tmp_path):
    from slip_identification.cli import analyze_bag

    bag, truth = _labhex(tmp_path, 'b')
    out = analyze_bag(bag, {**LABHEX, 'offset': 0.030})
    run = out['run']
    assert run['offset_s'] == 0.030
    assert run['frame']['geometry_damping_time_s'] == 0.0       # undamped kept
    assert abs(run['frame']['pitch_offset_deg']) < 0.5          # was -3.37 deg
    assert np.max(np.abs(_edge_errors_ms(out, truth))) < 3.0    # was 11.7 ms
    assert any('undamped fit is kept' in n for n in run['notes'])


def _runner(lag_s: float, rate_hz: float = 100.0):
    """Six legs in two tripods, 0.16 s half-sine hip efforts every 0.36 s stride, sampled at
    ``rate_hz``; the geometric touchdowns ``lag_s`` after the efforts' true start."""
    period, stance = 0.36, 0.16
    tj = np.arange(0.0, 6.0, 1.0 / rate_hz)
    effort = np.zeros((tj.size, len(LEGS)))
    contacts = {}
    for k, leg in enumerate(LEGS):
        td = np.arange(0.2 + (0.5 * period if k >= 3 else 0.0), 5.6, period)
        for t0 in td:
            on = (tj >= t0) & (tj < t0 + stance)
            effort[on, k] = 2.0 * np.sin(np.pi * (tj[on] - t0) / stance)
        contacts[leg] = np.column_stack([td + lag_s, td + lag_s + stance])
    names = tuple(f'{leg}_hip' for leg in LEGS)
    return contacts, names, tj, effort


def _check(lag_s: float) -> RunResult:
    res = RunResult()
    contacts, names, tj, effort = _runner(lag_s)
    gfit = types.SimpleNamespace(flight=True, offset_s=0.0)
    _effort_contact_check(contacts, names, tj, effort, gfit, LegGeometry(), res)
    return res


def test_slowly_rising_efforts_do_not_make_exact_geometry_suspect():
    res = _check(0.0)
    lag, rise = res.frame['effort_contact_lag_s'], res.frame['effort_onset_rise_s']
    assert -0.009 < lag < -0.0065          # the 15 % threshold crossed about 7 ms late
    assert 0.006 < rise < 0.009            # ... which the onset's rise measures
    assert res.warnings == []              # was: "the leg description does not fit"


def test_a_real_lag_is_still_said():
    for lag_s in (-0.012, 0.012):
        res = _check(lag_s)
        assert any('does not fit this robot' in w for w in res.warnings), lag_s
