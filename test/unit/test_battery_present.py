"""BatteryState.present: samples of a battery that is not there are not measurements."""
from hexapod_common.battery import AbsentBatteryFilter, prepare_battery_samples
from hexapod_common.conversions import BatterySample


def _samples(present, volts=12.0, amps=-3.0, t0=0.0, source=''):
    return [BatterySample(t0 + 0.01 * k, volts, amps, float('nan'), source, p)
            for k, p in enumerate(present)]


def test_a_driver_that_never_sets_present_is_kept():
    samples = _samples([False] * 50)
    out, notes = prepare_battery_samples(samples)
    assert out == samples and not notes


def test_absent_after_present_is_left_out_and_noted():
    samples = _samples([True] * 20 + [False] * 10 + [True] * 20)
    out, notes = prepare_battery_samples(samples)
    assert len(out) == 40 and all(b.present for b in out)
    assert any('10 /battery_state sample(s) with present = false' in n for n in notes)


def test_zero_volts_and_amps_while_absent_are_left_out_even_first():
    samples = (_samples([False] * 5, volts=0.0, amps=0.0)
               + _samples([False] * 20, t0=1.0))
    f = AbsentBatteryFilter()
    assert [f.keep(s) for s in samples] == [False] * 5 + [True] * 20
    assert f.dropped == 5 and 't = 0.000 s' in f.note()


def test_per_source():
    f = AbsentBatteryFilter()
    assert f.keep(BatterySample(0.0, 12.0, -1.0, 0.0, 'servo', True))
    assert f.keep(BatterySample(0.1, 5.0, -1.0, 0.0, 'logic', False))     # never present
    assert not f.keep(BatterySample(0.2, 0.1, 0.0, 0.0, 'servo', False))
