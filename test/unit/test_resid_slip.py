"""SLIP residual loop (issue 8): stances simulated with leg damping, or with hip torque, select
that extension and lower the held-out nerr; pure SLIP stances select nothing."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from slip_identification.errors import SlipDataError
from slip_identification.model import SlipModel
from slip_identification.residuals import (
    SlipExtensionSelection,
    fit_slip_candidates,
    slip_loop_document,
)
from slip_identification.synthetic import make_stance


def stances(ext: str | None, value: float, n: int = 9, seed: int = 0):
    """Stances through 120 Hz motion capture with 0.2 mm noise (the paper's preprocessing)."""
    rng = np.random.default_rng(seed)
    model = SlipModel(extensions=(ext,) if ext else ())
    out = []
    for i in range(n):
        p = [rng.uniform(1500, 4000), rng.uniform(0.13, 0.17), rng.uniform(0.2, 1.8)]
        p += [value] if ext else []
        out.append(make_stance(np.array(p), speed_mps=rng.uniform(0.5, 1.0),
                               angle_rad=rng.uniform(0.2, 0.35), vz_mps=rng.uniform(-0.2, 0.0),
                               model=model, sample_hz=120.0, noise_m=0.0002, rng=rng,
                               t0_s=float(i), label=f's{i}').stance)
    return out


def run_loop(ext, value):
    fits = fit_slip_candidates(stances(ext, value), maxiter=3000)
    return slip_loop_document(SlipExtensionSelection().fit(fits))


@pytest.mark.parametrize('ext,value', [('leg_damping', 100.0), ('hip_torque', 1.0),
                                       ('hip_torque', -1.0)])
def test_extension_in_the_data_is_selected_and_lowers_nerr(ext, value):
    doc = run_loop(ext, value)
    assert doc['effects_added'] == [ext], doc['summary']
    assert doc['heldout']['rmse_after'] < 0.8 * doc['heldout']['rmse_before']
    chosen = next(c for c in doc['candidates'] if c['selected'])
    np.testing.assert_allclose(chosen['params'][ext], value, rtol=0.2)
    assert doc['model'] == 'slip' and doc['unit'] == 'nerr'


def test_pure_slip_selects_nothing():
    doc = run_loop(None, 0.0)
    assert doc['effects_added'] == []
    assert doc['heldout']['rmse_after'] == doc['heldout']['rmse_before']
    assert 'plain SLIP is kept' in doc['summary']


def test_too_few_stances_is_a_clear_error():
    fits = fit_slip_candidates(stances(None, 0.0, n=2))
    with pytest.raises(SlipDataError, match='too little data to split'):
        SlipExtensionSelection().fit(fits)


def test_cli_slip_writes_residuals_json(tmp_path):
    edubot = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from hexapod_energy.residuals_cli import add_cli

    bag = edubot.write_edubot_bag(tmp_path / 'run', 'running', duration_s=4.0, seed=1,
                                  effects={'leg_damping': 20.0})
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(['residuals', '--slip', str(bag), '--out', str(tmp_path / 'out'),
                          '--box', '-10', '-10', '-10', '10', '10', '10'])
    assert args.func(args) == 0
    doc = json.loads((tmp_path / 'out' / 'residuals.json').read_text())
    assert doc['model'] == 'slip' and doc['unit'] == 'nerr'
    assert {c['name'] for c in doc['candidates']} == {'leg_damping', 'hip_torque'}
    assert doc['stances']['count'] >= 3
    assert (tmp_path / 'out' / 'residual_slip_nerr.png').is_file()


class _Fit:
    """A per-stance fit result as the selection reads it."""

    def __init__(self, nerr: float, bic: float, params: dict, stderr: dict) -> None:
        self.nerr, self._bic, self.params, self.stderr = nerr, bic, params, stderr

    def bic(self) -> float:
        return self._bic


def _fits(damping: list[float], se: float = 5.0) -> dict:
    n = len(damping)
    return {'slip': [_Fit(0.30, 0.0, {}, {}) for _ in range(n)],
            'leg_damping': [_Fit(0.10, -50.0, {'leg_damping': c}, {'leg_damping': se})
                            for c in damping],
            'hip_torque': [_Fit(0.30, 0.0, {'hip_torque': 0.0}, {'hip_torque': 1.0})
                           for _ in range(n)]}


def test_a_damping_that_is_not_one_property_of_the_robot_is_not_added():
    """An outside review's SLIP loop named a missed leg damping of -31.2 N s/m (per stance -105
    to +4462 N s/m): every stance's fit improved, but the values changed sign and the median was
    negative. Now the median must be physical (damping > 0), 75 % of the stances must share its
    sign and it must stand out of the spread between stances; the summary says why not."""
    mixed = [-105.0, -40.0, -31.2, 4462.0, 4430.0, -20.0, 4450.0, -60.0, -31.0, 10.0, -50.0,
             4420.0]
    doc = slip_loop_document(SlipExtensionSelection().fit(_fits(mixed)))
    assert doc['effects_added'] == []
    c = next(c for c in doc['candidates'] if c['name'] == 'leg_damping')
    assert c['improves'] and any('unphysical' in w for w in c['rejected_because'])
    assert any('sign varies' in w for w in c['rejected_because'])
    assert 'not one property of the robot' in doc['summary']
    consistent = [95.0, 102.0, 110.0, 98.0, 105.0, 99.0, 101.0, 97.0, 103.0, 100.0, 96.0, 104.0]
    doc = slip_loop_document(SlipExtensionSelection().fit(_fits(consistent)))
    assert doc['effects_added'] == ['leg_damping']
