"""SLIP residual loop, outside review H (simulated EduBot data): a consistent negative leg
damping is said to be energy added during stance, not "not one property"; a candidate that
lowered the held-out error and was refused for another reason is named with it; a step of the
per-stance nerr over the runs and stances standing apart are reported; a near-tied second
extension is named; the robot mass is used, recorded, and a warning given when assumed."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from slip_identification.residuals import SlipExtensionSelection, slip_loop_document


class _Fit:
    """A per-stance fit result as the selection reads it."""

    def __init__(self, nerr: float, bic: float, params: dict, stderr: dict,
                 label: str = '', touchdown_s: float = 0.0) -> None:
        self.nerr, self._bic, self.params, self.stderr = nerr, bic, params, stderr
        self.label, self.touchdown_s = label, touchdown_s

    def bic(self) -> float:
        return self._bic


def _fits(n: int = 24, *, slip=None, ld=None, ht=None) -> dict:
    """Two runs of n/2 stances; each of slip/ld/ht: (nerr per stance, bic, values, se)."""
    lab = [f'run{i // (n // 2)}#{i}' for i in range(n)]
    t = [0.2 * (i % (n // 2)) for i in range(n)]
    slip = slip or (np.full(n, 0.30), 0.0)
    ld = ld or (np.full(n, 0.30), 0.0, np.zeros(n), 1.0)
    ht = ht or (np.full(n, 0.30), 0.0, np.zeros(n), 1.0)
    out = {'slip': [_Fit(slip[0][i], slip[1], {}, {}, lab[i], t[i]) for i in range(n)]}
    for name, (nerr, bic, vals, se) in (('leg_damping', ld), ('hip_torque', ht)):
        out[name] = [_Fit(nerr[i], bic, {name: vals[i]}, {name: se}, lab[i], t[i])
                     for i in range(n)]
    return out


def _doc(fits: dict) -> dict:
    return slip_loop_document(SlipExtensionSelection().fit(fits))


def test_consistent_negative_damping_is_energy_added_not_a_fudge():
    """Review: clean running fitted -61.5 N s/m on median, all 28 stances negative, held-out
    0.122 -> 0.096; the summary said "not one property of the robot"."""
    rng = np.random.default_rng(1)
    n = 24
    vals = -60.0 + 15.0 * rng.standard_normal(n)
    doc = _doc(_fits(n, slip=(np.full(n, 0.12), 0.0),
                     ld=(np.full(n, 0.096), -47.0, vals, 13.6)))
    assert doc['effects_added'] == []
    c = next(c for c in doc['candidates'] if c['name'] == 'leg_damping')
    assert c['consistency'] == 'unphysical_sign'
    assert 'not one property' not in doc['summary']
    assert 'energy is added during stance' in doc['summary']
    assert 'leg damping cannot be measured' in doc['summary']


def test_a_candidate_that_lowers_heldout_error_is_named_with_its_reason():
    """Review: clean pace, hip_torque 0.343 -> 0.237 held-out, median dBIC -382/stance,
    per-stance values -167,953 to +83 N m; the summary said neither lowered the error."""
    n = 24
    vals = np.array([0.85, -2.0, 83.0, -167953.0, 1.2, -0.5] * 4)
    doc = _doc(_fits(n, slip=(np.full(n, 0.343), 0.0),
                     ht=(np.full(n, 0.237), -382.0, vals, 10.0)))
    assert doc['effects_added'] == []
    assert 'Neither' not in doc['summary']
    assert 'hip_torque lowered the held-out error (rms nerr 0.343 -> 0.237' in doc['summary']
    assert 'its own standard errors' in doc['summary']
    c = next(c for c in doc['candidates'] if c['name'] == 'hip_torque')
    assert c['lowers_heldout'] and not c['improves']
    assert c['params']['per_stance_range'] == [-167953.0, 83.0]


def test_near_tied_second_extension_is_named():
    """Review: soft ground, hip_torque 0.0875 added, leg_damping 0.0880 passed every check
    and was not mentioned."""
    rng = np.random.default_rng(2)
    n = 24
    doc = _doc(_fits(n, slip=(np.full(n, 0.099), 0.0),
                     ld=(np.full(n, 0.0880), -18.0, 20.0 + rng.standard_normal(n), 2.0),
                     ht=(np.full(n, 0.0875), -20.0, -0.7 + 0.05 * rng.standard_normal(n),
                         0.1)))
    assert doc['effects_added'] == ['hip_torque']
    assert [a['name'] for a in doc['alternatives']] == ['leg_damping']
    assert 'leg_damping (median' in doc['summary'] and 'nearly as well' in doc['summary']
    # far apart: not named as an alternative
    doc = _doc(_fits(n, slip=(np.full(n, 0.099), 0.0),
                     ld=(np.full(n, 0.0930), -18.0, 20.0 + rng.standard_normal(n), 2.0),
                     ht=(np.full(n, 0.0875), -20.0, -0.7 + 0.05 * rng.standard_normal(n),
                         0.1)))
    assert doc['alternatives'] == []


def test_a_step_in_the_nerr_over_the_runs_is_reported():
    """Review: damping switched on half-way, a knocked marker: "plain SLIP is kept", nothing
    on the error changing over time."""
    rng = np.random.default_rng(3)
    n = 32
    base = 0.12 * np.exp(0.08 * rng.standard_normal(n))
    stepped = base * np.where(np.arange(n) % (n // 2) >= n // 4, 1.6, 1.0)
    doc = _doc(_fits(n, slip=(stepped, 0.0)))
    u = doc['unexplained']
    assert u['significant'] and u['pattern'] == 'step', u
    assert [round(r['at_s'], 1) for r in u['per_run']] == [1.6, 1.6]
    assert 'steps within runs' in doc['summary']
    doc = _doc(_fits(n, slip=(base, 0.0)))
    assert not doc['unexplained']['significant']
    assert 'changes over time' not in doc['summary']


def test_a_stance_standing_apart_is_listed_and_left_out():
    from slip_identification.residuals import nerr_time_pattern

    rng = np.random.default_rng(4)
    nerr = 0.23 * np.exp(0.05 * rng.standard_normal(20))
    nerr[7] = 0.82
    u = nerr_time_pattern(['a'] * 20, np.arange(20) * 0.2, nerr)
    assert [round(x['at_s'], 1) for x in u['isolated']] == [1.4]
    assert not u['significant']
    nerr[7] = 0.30
    assert nerr_time_pattern(['a'] * 20, np.arange(20) * 0.2, nerr)['isolated'] == []


def test_slip_loop_uses_records_and_warns_about_the_robot_mass(tmp_path):
    """Review: --robot-mass 3.97 was accepted and ignored (3.31 kg hard-wired), not recorded,
    no warning; fitted effects scale with the mass."""
    edubot = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from hexapod_energy.residuals_cli import add_cli, run_slip_loop

    bag = edubot.write_edubot_bag(tmp_path / 'run', 'running', duration_s=4.0, seed=1,
                                  effects={'hip_torque': 0.2})
    box = [-10, -10, -10, 10, 10, 10]
    assumed = run_slip_loop([str(bag)], None, plots=False, box=box)
    assert assumed['mass_kg'] == pytest.approx(3.31)
    assert any('3.31 kg assumed' in w for w in assumed['warnings'])
    ap = argparse.ArgumentParser()
    add_cli(ap.add_subparsers(dest='command', required=True))
    args = ap.parse_args(['residuals', '--slip', str(bag), '--out', str(tmp_path / 'out'),
                          '--robot-mass', '6.62', '--no-plots', '--no-progress',
                          '--box', *map(str, box)])
    assert args.func(args) == 0
    doc = json.loads((tmp_path / 'out' / 'residuals.json').read_text())
    assert doc['mass_kg'] == pytest.approx(6.62) and doc['warnings'] == []
    # the loop's stances are hexapod-analyze slip's at the given mass, whose leg-stiffness
    # check (stiffness per kg times the mass against EduBot's legs) moves the offset and the
    # edges at twice the robot's mass: the per-stance values no longer scale 2x stance by
    # stance (they had, on the clock's windows); that they take the mass is pinned by the
    # payload below (the same point mass, the same values to 1e-9) and by this
    for name in ('leg_damping', 'hip_torque'):
        a = next(c for c in assumed['candidates'] if c['name'] == name)['params']
        b = next(c for c in doc['candidates'] if c['name'] == name)['params']
        assert np.shape(a['per_stance']) != np.shape(b['per_stance']) or \
            not np.allclose(a['per_stance'], b['per_stance'])
    args = ap.parse_args(['residuals', '--slip', str(bag), '--out', str(tmp_path / 'o2'),
                          '--mass', 'nan', '--no-plots', '--no-progress'])
    assert args.func(args) == 2
    # a payload rides on the template's point mass too (ignored without a word before: a
    # review of the change)
    args = ap.parse_args(['residuals', '--slip', str(bag), '--out', str(tmp_path / 'o3'),
                          '--robot-mass', '3.31', '--robot-payload', '3.31', '--no-plots',
                          '--no-progress', '--box', *map(str, box)])
    assert args.func(args) == 0
    pay = json.loads((tmp_path / 'o3' / 'residuals.json').read_text())
    assert pay['mass_kg'] == pytest.approx(3.31) and pay['payload_kg'] == pytest.approx(3.31)
    for name in ('leg_damping', 'hip_torque'):
        a = next(c for c in doc['candidates'] if c['name'] == name)['params']
        b = next(c for c in pay['candidates'] if c['name'] == name)['params']
        np.testing.assert_allclose(b['per_stance'], a['per_stance'], rtol=1e-9)


def test_time_pattern_leaves_failed_fits_and_short_runs_alone():
    """A NaN nerr read as a trend at p 0.001, an infinite one stood apart as 'xinf', and in a
    run of 3 stances any stance at twice the median stood apart (a review of the change)."""
    from slip_identification.residuals import nerr_time_pattern

    rng = np.random.default_rng(0)
    t = np.arange(12, dtype=float)
    e = 0.05 * np.exp(0.05 * rng.standard_normal(12))
    for bad in (np.nan, np.inf):
        got = nerr_time_pattern(['a'] * 12, t, np.where(t == 5, bad, e), permutations=199)
        assert not got['significant'] and got['isolated'] == []
        assert got['per_run'] == [] or got['per_run'][0]['stances'] == 11
    short = nerr_time_pattern(['b'] * 3, t[:3], np.array([0.05, 0.05, 0.12]), permutations=99)
    assert short['isolated'] == []
