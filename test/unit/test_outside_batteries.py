"""Several batteries on one ``/battery_state`` (a servo pack and a logic pack, told apart by
``header.frame_id``): their input powers are summed, or ``--battery-source`` keeps one.

Before: the interleaved samples were read as one battery's, and every average over time gave
the mean of the packs' powers weighted by their rates: 30 W (servo pack, 50 Hz) and 5 W (logic
pack, 10 Hz) read as 25.8 W instead of 35 W.
"""

from __future__ import annotations

import json

import pytest

from hexapod_common.analyze_cli import main as analyze
from hexapod_common.battery import BATTERY_SOURCE_ENV, BatteryCombiner, combine_battery_samples
from hexapod_common.conversions import BatterySample
from hexapod_common.testbags import rewrite_bag, write_two_battery_robot_bag
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.errors import BagContentError
from hexapod_energy.residuals import read_residual_run


def _millivolts(topic, msg) -> None:
    if topic == '/battery_state':
        msg.voltage *= 1000.0


def _power(s: BatterySample) -> float:
    return -s.voltage_v * s.current_a


def test_one_battery_passes_unchanged():
    comb = BatteryCombiner()
    samples = [BatterySample(0.1 * k, 12.0, -2.0, 25.0, 'supply') for k in range(30)]
    assert [comb.add(s) for s in samples] == samples
    assert comb.finish() == []
    out, notes = combine_battery_samples(samples)
    assert out == samples and notes == []


def test_two_packs_are_summed_at_every_sample():
    servo = [BatterySample(0.02 * k, 12.0, -30.0 / 12.0, 30.0, 'servo') for k in range(500)]
    logic = [BatterySample(0.003 + 0.1 * k, 7.4, -5.0 / 7.4, 30.0, 'logic') for k in range(100)]
    out, notes = combine_battery_samples(servo + logic)
    assert len(out) == len(servo) + len(logic) - 1       # one per sample from both on
    assert all(_power(s) == pytest.approx(35.0, rel=1e-12) for s in out)
    assert all(s.voltage_v == 12.0 for s in out)          # the first source's voltage
    assert "2 batteries on /battery_state ('servo', 'logic')" in notes[0]


def test_expected_sources_hold_until_each_reported():
    a = [BatterySample(0.1 * k, 12.0, -1.0, 0.0, 'a') for k in range(10)]
    b = [BatterySample(0.55 + 0.1 * k, 12.0, -2.0, 0.0, 'b') for k in range(5)]
    out, notes = combine_battery_samples(a + b)
    assert out[0].t_s == pytest.approx(0.55)             # nothing before 'b' reported
    assert all(_power(s) == pytest.approx(36.0) for s in out)
    assert any('6 battery sample(s) before every source' in n for n in notes)


def test_live_combiner_learns_a_late_source_and_drops_a_silent_one():
    comb = BatteryCombiner()                               # live: sources unknown
    powers = []
    for k in range(100):
        t = 0.1 * k
        powers.append(_power(comb.add(BatterySample(t, 12.0, -1.0, 0.0, 'a'))))
        if 2.0 <= t < 4.0:
            powers.append(_power(comb.add(BatterySample(t + 0.01, 12.0, -2.0, 0.0, 'b'))))
    assert powers[0] == pytest.approx(12.0)               # 'a' alone
    assert max(powers) == pytest.approx(36.0)              # both
    assert powers[-1] == pytest.approx(12.0)               # 'b' silent > 2 s: left out
    text = ' '.join(comb.finish())
    assert "'b' appeared at t = 2.010 s" in text and "'b' silent for more than 2.0 s" in text


def test_same_pack_published_twice_is_noted():
    a = [BatterySample(0.02 * k, 12.0, -2.5, 0.0, 'bms') for k in range(100)]
    b = [BatterySample(0.02 * k + 0.01, 12.01, -2.51, 0.0, 'power_board') for k in range(100)]
    out, notes = combine_battery_samples(a + b)
    assert any('same voltage' in n and '--battery-source' in n for n in notes)
    kept, notes = combine_battery_samples(a + b, select='bms')
    assert kept == a and any('100 /battery_state sample(s) of other sources' in n
                             for n in notes)
    with pytest.raises(ValueError, match="'nope' not on /battery_state.*'bms', 'power_board'"):
        combine_battery_samples(a + b, select='nope')


@pytest.fixture(scope='module')
def two_pack_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp('packs') / 'two_packs'
    write_two_battery_robot_bag(path)
    return path


def test_robot_bag_input_power_is_the_sum(two_pack_bag):
    run = read_robot_bag(two_pack_bag, mass_kg=2.2)
    assert run.power_in_w == pytest.approx(35.0, rel=2e-3)    # was 25.8 W (the mean)
    assert any('2 batteries on /battery_state' in n for n in run.extra['notes'])
    res = read_residual_run(two_pack_bag)
    assert float(res.power_w.mean()) == pytest.approx(35.0, rel=3e-3)
    assert any('2 batteries' in n for n in res.notes)


def test_battery_source_keeps_one_pack(two_pack_bag, monkeypatch):
    monkeypatch.setenv(BATTERY_SOURCE_ENV, 'servo')
    run = read_robot_bag(two_pack_bag, mass_kg=2.2)
    assert run.power_in_w == pytest.approx(30.0, rel=2e-3)
    monkeypatch.setenv(BATTERY_SOURCE_ENV, 'main')
    with pytest.raises(BagContentError, match="'main' not on /battery_state.*'servo'"):
        read_robot_bag(two_pack_bag, mass_kg=2.2)


def test_cli_option(two_pack_bag, tmp_path, capsys):
    """``hexapod-analyze --battery-source`` reaches the bag readers; the environment is
    restored afterwards."""
    out = tmp_path / 'out'
    bench = tmp_path / 'bench'
    from test_energy_cli import _write_bench
    _write_bench(bench)
    assert analyze(['--battery-source', 'logic', 'energy', '--bench', str(bench),
                    '--robot', str(two_pack_bag), '--out', str(out)]) == 0
    data = json.loads((out / 'energy.json').read_text())
    assert data['robot_runs'][0]['measured_power_in_w'] == pytest.approx(5.0, rel=1e-6)
    import os
    assert BATTERY_SOURCE_ENV not in os.environ
    assert analyze(['--battery-source', 'nope', 'energy', '--bench', str(bench),
                    '--robot', str(two_pack_bag), '--out', str(out)]) != 0
    assert "'nope' not on /battery_state" in capsys.readouterr().err


def test_battery_source_leaves_a_one_battery_bag_alone():
    """A bench supply (one source) read beside robot bags of two packs: kept, noted."""
    one = [BatterySample(0.1 * k, 12.0, -1.0, 0.0, 'supply') for k in range(5)]
    out, notes = combine_battery_samples(one, select='servo')
    assert out == one and "one battery ('supply'), kept" in notes[0]
    comb = BatteryCombiner(select='servo')                 # live: strict, noted
    assert all(comb.add(s) is None for s in one * 4)
    assert "'servo' not seen in 20 samples; the topic carries 'supply'" in comb.finish()[0]


def test_a_monitor_that_fills_zero_current_is_refused(tmp_path):
    """A battery monitor without a current sensor that publishes current 0 (not NaN): the
    robot run read 0 W input power (efficiency infinite) with no warning; now refused by name
    (``slip`` keeps the run, power null, noted)."""
    from test_outside_slow_sensors import _write_slow_battery_robot

    _write_slow_battery_robot(tmp_path / 'z', battery_hz=50.0, power_w=0.0)
    with pytest.raises(BagContentError, match='has current 0: the monitor does not measure'):
        read_robot_bag(tmp_path / 'z', mass_kg=2.0)
    with pytest.raises(BagContentError, match='has current 0'):
        read_residual_run(tmp_path / 'z')
    from hexapod_common.battery import unmeasured_power
    assert unmeasured_power([12.0] * 5, [0.0] * 4 + [-0.1]) is None   # one real sample
    assert 'voltage 0' in unmeasured_power([0.0] * 5, [-1.0] * 5)


def test_millivolts_and_milliamps_are_scaled(tmp_path):
    """A BMS or INA2xx driver publishing mV and mA: the run read 1000 (or 10^6) times its
    power silently; now scaled per source, noted, same figures as the bag in V and A."""
    from hexapod_common.battery import prepare_battery_samples

    v = [BatterySample(0.01 * k, 12.0, -2.5, 0.0, 'pack') for k in range(50)]
    mv = [BatterySample(s.t_s, 12000.0, -2500.0, 0.0, 'pack') for s in v]
    out, notes = prepare_battery_samples(mv)
    assert out == v and 'voltage and current in milli-units (median 12000 and 2500)' in notes[0]
    out, notes = prepare_battery_samples(v)
    assert out == v and notes == []
    from test_outside_slow_sensors import _write_slow_battery_robot

    _write_slow_battery_robot(tmp_path / 'v', battery_hz=50.0)
    ref = read_robot_bag(tmp_path / 'v', mass_kg=2.0)
    rewrite_bag(tmp_path / 'v', tmp_path / 'mv', _millivolts)
    got = read_robot_bag(tmp_path / 'mv', mass_kg=2.0)
    assert got.power_in_w == pytest.approx(ref.power_in_w, rel=1e-9)
    assert any('voltage in milli-units' in n for n in got.extra['notes'])


def test_a_slow_monitor_is_summed_before_its_second_report():
    """A logic-pack monitor reporting every 3 s beside a 10 Hz servo pack: its interval is
    unknown until its second report. It was left out of the sum from 2 s (``STALE_S``) to that
    report (30 W instead of 35 W for a second, noted as silent); now it is kept, and one that
    stops after its first report still leaves the sum (after ``FIRST_REPORT_STALE_S``)."""
    servo = [BatterySample(0.1 * k, 12.0, -30.0 / 12.0, 0.0, 'servo') for k in range(200)]
    logic = [BatterySample(0.05 + 3.0 * k, 7.4, -5.0 / 7.4, 0.0, 'logic') for k in range(7)]
    out, notes = combine_battery_samples(servo + logic)
    assert all(_power(s) == pytest.approx(35.0, rel=1e-12) for s in out)
    assert not any('silent' in n for n in notes)
    # live, a monitor that reports once and dies: summed for 10 s, then left out
    comb = BatteryCombiner()
    powers = []
    for k in range(200):
        powers.append(_power(comb.add(BatterySample(0.1 * k, 12.0, -2.5, 0.0, 'servo'))))
        if k == 5:
            powers.append(_power(comb.add(BatterySample(0.55, 7.4, -5.0 / 7.4, 0.0, 'logic'))))
    assert powers[-1] == pytest.approx(30.0) and max(powers) == pytest.approx(35.0)
    assert sum(p == pytest.approx(35.0) for p in powers) == 101   # 0.55 s to 10.5 s
    assert "'logic' silent for more than 10.0 s" in ' '.join(comb.finish())
