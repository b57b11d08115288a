"""The bench's power-to-label lag is estimated against the schedule's own timeline (each phase
boundary where ``/gait/phase``'s clock puts it), and a lag two walking frequencies cannot tell
from another peak is not applied.

The estimate took the nearest label, which moves each boundary between two labels to their
midpoint by an amount that depends on which labels were recorded. On the simulated bench with
only 0.75 and 1.5 Hz sessions (no clock offset) a ``/gait/phase`` thinned to 50 Hz applied
-0.257 s (every other label) or -0.037 s (the others): the phase powers then mixed stance and
swing. With the clock the estimate is the same at 100 and 50 Hz (-0.034 s, not applied).
Two frequencies fix the clock offset and the waveform's phase-locked delay with nothing left
over: a comparable peak further out (which the smaller offset beat) made a 0.12 s offset read
0.072 s and a 0.3 s one -0.130 s, applied.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import hexapod_energy.bag_io as bag_io
from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy.bag_io import BenchData, bench_phase_samples, read_bench_bag
from hexapod_energy.single_leg import power_label_lag_s

G = 9.81
BETA = 0.5
POWER_DT = 0.005     # the benches' 200 Hz power


def p_stance(load: float, f: float) -> float:
    return 2.0 + load + 1.5 * f + 3.0 * load * f


def p_swing(load: float, f: float) -> float:
    return 2.0 + 0.2 * load + 3.0 * f + f * f


def schedule_bench(*, offset: float = 0.0, label_hz: float = 100.0, label_start: float = 0.0,
                   phase_delay: float = 0.1, freqs=(0.0, 0.75, 1.5), loads=(0.0, 0.3),
                   walk_s: float = 8.0) -> BenchData:
    """Sessions back to back with a ``/gait/phase`` schedule (stamps from ``label_start``
    at ``label_hz``, with its clock); the power steps between the phase powers
    ``phase_delay`` cycle after the schedule (the waveform's own delay), its stamps
    ``offset`` s late (a clock offset)."""
    t0, t = 100.0, 100.0
    plan, sessions = [], []
    for k, (load, f) in enumerate((a, b) for a in loads for b in freqs):
        row = {'session_id': f's{k:03d}', 'load_kg': load, 'frequency_hz': f,
               'duty_factor': BETA}
        sessions.append(dict(row, t_s=t, state='heating'))
        sessions.append(dict(row, t_s=t + 1.0, state='walking'))
        plan.append((load, f, t + 1.0, t + 1.0 + walk_s))
        sessions.append(dict(row, t_s=t + 1.0 + walk_s, state='cooling'))
        t += 2.0 + walk_s

    def state(ts: np.ndarray, delay: float = 0.0):
        p, fz, z = np.zeros(ts.shape), np.zeros(ts.shape), np.zeros(ts.shape)
        st = np.ones(ts.shape, bool)
        phase, period = np.full(ts.shape, np.nan), np.full(ts.shape, np.nan)
        seen = np.zeros(ts.shape, bool)
        for load, f, w0, w1 in plan:
            m = (ts >= w0 - 1.0) & (ts < w1 + 1.0) & ~seen
            seen |= m
            p[m], fz[m] = 2.0 + load, G * (load + 0.2)
            walk = m & (ts >= w0) & (ts < w1)
            if f <= 0:
                continue
            ph = ((ts[walk] - w0) * f) % 1.0
            p[walk] = np.where(((ts[walk] - w0) * f - delay) % 1.0 < BETA, p_stance(load, f),
                               p_swing(load, f))
            fz[walk] = np.where(ph < BETA, G * (load + 0.2), 0.0)
            z[walk] = np.where(ph < BETA, 0.0, 0.04 * np.sin(np.pi * (ph - BETA) / (1 - BETA)))
            st[walk], phase[walk], period[walk] = ph < BETA, ph, 1.0 / f
        return p, fz, z, st, phase, period

    tp = np.arange(t0, t, POWER_DT)
    p = state(tp, phase_delay)[0]
    tf = np.arange(t0, t, 0.005)
    _p, fz, z, *_ = state(tf)
    tl = np.arange(t0, t, 1.0 / label_hz) + label_start
    *_, st, phase, period = state(tl)
    clock = np.stack([phase, period, np.where(np.isfinite(period), BETA, np.nan)], axis=1)
    return BenchData(path='synthetic', battery_t_s=tp + offset,
                     battery_v=np.full(tp.shape, 12.0), battery_a=-p / 12.0,
                     force_t_s=tf, force_z_n=fz, tip_t_s=tf, tip_z_m=z, sessions=sessions,
                     schedule_t_s=tl, schedule_stance=st, schedule_clock=clock)


def thinned(data: BenchData, keep: np.ndarray) -> BenchData:
    return dataclasses.replace(data, schedule_t_s=data.schedule_t_s[keep],
                               schedule_stance=data.schedule_stance[keep],
                               schedule_clock=data.schedule_clock[keep])


def not_applied(diag) -> bool:
    return any('lags the phase labels' in w and 'not applied' in w for w in diag['warnings'])


@pytest.fixture(scope='module')
def sim_bench(tmp_path_factory):
    """The simulated bench with only 0.75 and 1.5 Hz walking sessions (and 0 Hz), 2 loads,
    no clock offset, its /gait/phase at 100 Hz."""
    path = tmp_path_factory.mktemp('lag_bench') / 'bench'
    plan = BenchPlan(loads_kg=(0.0, 0.515), frequencies_hz=(0.0, 0.75, 1.5), walk_s=4.0,
                     max_cool_s=5.0)
    write_trace(simulate_bench(plan, seed=3), path)
    return read_bench_bag(path)


#: which /gait/phase messages are kept: every one, every other (both ways), 20 and 10 Hz
KEEP = {'100 Hz': (1, 0), '50 Hz odd': (2, 1), '50 Hz even': (2, 0), '20 Hz': (5, 0),
        '10 Hz': (10, 3)}


def test_a_thinned_schedule_applies_no_lag_on_the_simulated_bench(sim_bench):
    idx = np.arange(sim_bench.schedule_t_s.size)
    found = {}
    for name, (step, first) in KEEP.items():
        _samples, diag = bench_phase_samples(thinned(sim_bench, idx % step == first))
        # no clock offset: none applied (the nearest label applied -0.257 s with the odd
        # labels at 50 Hz, -0.037 s with the even ones)
        assert abs(diag['power_lag_s']) <= POWER_DT, (name, diag['power_lag'])
        if diag['phase_split'] == 'schedule':
            found[name] = diag['power_lag']['lag_s']
        else:   # 20 and 10 Hz do not cover the sessions: the contact split, its own labels
            assert name in ('20 Hz', '10 Hz')
    # the estimate does not depend on which labels were recorded (the nearest label read
    # -0.011, -0.257 and -0.037 s)
    assert set(found) == {'100 Hz', '50 Hz odd', '50 Hz even'}
    assert max(found.values()) - min(found.values()) <= POWER_DT


@pytest.mark.parametrize('shift', [0.12, 0.3])
def test_a_clock_offset_on_the_simulated_bench_is_not_applied_wrong(sim_bench, shift):
    """Two frequencies and a broad waveform: the offset is either got back or not applied
    (the nearest label applied -0.137 s for 0.12 s with every other label)."""
    data = dataclasses.replace(sim_bench, battery_t_s=sim_bench.battery_t_s + shift)
    idx = np.arange(data.schedule_t_s.size)
    for name in ('100 Hz', '50 Hz odd', '50 Hz even'):
        step, first = KEEP[name]
        _samples, diag = bench_phase_samples(thinned(data, idx % step == first))
        lag = diag['power_lag_s']
        assert lag == 0.0 or lag == pytest.approx(shift, abs=0.01), (name, diag['power_lag'])


@pytest.mark.parametrize('offset', [0.03, 0.12, -0.12])
@pytest.mark.parametrize('label_hz, label_start', [(100.0, 0.0037), (50.0, 0.0137)])
def test_a_known_offset_is_got_back_at_100_and_50_hz(offset, label_hz, label_start):
    # labels off the power grid: the nearest label read 0.038 / 0.040 s for 0.03 s
    data = schedule_bench(offset=offset, label_hz=label_hz, label_start=label_start)
    samples, diag = bench_phase_samples(data)
    assert diag['phase_split'] == 'schedule'
    assert diag['power_lag_s'] == pytest.approx(offset, abs=1.2 * POWER_DT)
    assert any('lags the phase labels' in w and 'moved back' in w for w in diag['warnings'])
    # the phase powers of the bench without the offset, within a power sample per boundary
    ref, _ = bench_phase_samples(schedule_bench(label_hz=label_hz, label_start=label_start))
    for a, b in zip(samples, ref):
        assert a.p_stance_w == pytest.approx(b.p_stance_w, rel=0.02)
        assert a.p_swing_w == pytest.approx(b.p_swing_w, rel=0.02)


@pytest.mark.parametrize('label_hz, label_start', [(100.0, 0.0037), (50.0, 0.0137)])
def test_no_offset_reads_none_at_100_and_50_hz(label_hz, label_start):
    _samples, diag = bench_phase_samples(schedule_bench(label_hz=label_hz,
                                                        label_start=label_start))
    assert diag['power_lag_s'] == 0.0
    assert abs(diag['power_lag']['lag_s']) <= POWER_DT


@pytest.mark.parametrize('offset', [0.33, -0.33, 0.34])
@pytest.mark.parametrize('label_hz, label_start', [(100.0, 0.0037), (50.0, 0.0137)])
def test_an_offset_near_half_the_alias_period_is_a_warning_not_a_shift(offset, label_hz,
                                                                       label_start):
    """0.75 and 1.5 Hz: the offset is known modulo 2/3 s, and +-1/3 s are the same split
    (the 0.75 Hz sessions' stance and swing swapped). The nearest label applied -0.318 s for
    0.34 s (the 0.75 Hz phases swapped: 44 % off), -0.326 s for -0.33 s, or nothing in
    silence."""
    _samples, diag = bench_phase_samples(schedule_bench(offset=offset, label_hz=label_hz,
                                                        label_start=label_start))
    assert diag['power_lag_s'] == 0.0
    assert not_applied(diag)


def test_the_lag_is_the_same_at_any_label_rate_with_the_clock():
    """power_label_lag_s: the schedule's clock places the boundaries, so 100, 50, 20 and 10 Hz
    labels give one estimate, 0 (a phase-locked delay of 0.1 cycle, no clock offset); the
    nearest label read -0.013 to +0.014 s, by the labels' rate and first stamp."""
    def rows(label_hz, start, with_clock=True):
        out = []
        for f in (0.75, 1.5):
            tp = np.arange(0.0, 8.0, POWER_DT)
            p = np.where(((tp * f) - 0.1) % 1.0 < BETA, 3.0, 7.0)
            tl = np.arange(0.0, 8.0, 1.0 / label_hz) + start
            ph = (tl * f) % 1.0
            clock = np.stack([ph, np.full(tl.size, 1 / f), np.full(tl.size, BETA)], axis=1)
            out.append((tp, p, tl, ph < BETA, None, f) + ((clock,) if with_clock else ()))
        return out

    cases = [(hz, start) for hz in (100.0, 50.0, 20.0, 10.0) for start in (0.0, 0.0037, 0.031)]
    lags = [power_label_lag_s(rows(hz, start))['lag_s'] for hz, start in cases]
    assert max(np.abs(lags)) <= 0.001, lags
    nearest = [power_label_lag_s(rows(hz, start, with_clock=False))['lag_s']
               for hz, start in cases]
    assert max(nearest) - min(nearest) > 2 * POWER_DT


@pytest.mark.parametrize('frequencies, applied', [(2, False), (3, True)])
def test_a_comparable_peak_further_out_is_ambiguous_with_two_frequencies(monkeypatch,
                                                                         frequencies,
                                                                         applied):
    found = {'lag_s': -0.130, 'se_s': 0.008, 'phase_lag': -0.245, 'explained': 0.30,
             'explained_at_zero': 0.24, 'second': 0.953, 'second_lag_s': 0.302,
             'agree': 10, 'sessions': 10, 'frequencies': frequencies, 'search_s': 0.333,
             'alias_s': 0.667, 'edge': False}
    monkeypatch.setattr(bag_io, 'power_label_lag_s', lambda rows: dict(found))
    notes, warnings = [], []
    lag, _r = bag_io._power_lag_s(None, None, [], notes, warnings)
    assert (lag == pytest.approx(-0.130)) is applied
    assert any(('moved back' if applied else 'not applied') in w for w in warnings)
    assert any('no third' in w for w in warnings) is not applied
