"""A window the body enters the motion-capture volume in: its fallback note gives the real
reason. An outside review's client read, on a simulated EduBot walk (`hexapod-sim edubot
--gait walk --seed 2`, `hexapod-analyze energy --robot BAG`), "no motion-capture speed for
this window ...: its poses span 54 % of it (under 50 %; the body lost by the motion
capture?)": 54 % is not under 50 %, and the body was not lost; it entered the volume after
the window's start, which has no speed from the mocap by design (README, /mocap/body)."""

from __future__ import annotations

from hexapod_energy.descriptors import POSE_FALLBACK_NOTE, POSE_MIN_COVER, DescriptorAccumulator

from test_energy_review_live_core import run


def _fallbacks(out: list) -> list[tuple[float, str]]:
    return [(d.t_end_s - d.window_s, w) for d in out for w in d.warnings
            if w.startswith(POSE_FALLBACK_NOTE)]


def test_the_body_entering_the_volume_is_not_called_under_half_the_window() -> None:
    acc = DescriptorAccumulator(mass_kg=3.0)
    # no pose before 4.3 s: the window 4-5 s has poses over 70 % of it
    out = run(acc, lost=[(0.0, 4.3)])
    notes = [w for t0, w in _fallbacks(out) if abs(t0 - 4.0) < 1e-6]
    assert len(notes) == 1, _fallbacks(out)
    note = notes[0]
    assert '70 %' in note
    assert f'under {100 * POSE_MIN_COVER:.0f} %' not in note
    assert 'lost' not in note
    assert 'entered the motion-capture volume' in note
    assert 'gait schedule' in note


def test_a_window_with_little_tracking_still_says_under_half() -> None:
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, lost=[(4.7, 7.2)])   # the window 6-7 s: no pose at all
    notes = [w for t0, w in _fallbacks(out) if abs(t0 - 6.0) < 1e-6]
    assert len(notes) == 1
    assert f'under {100 * POSE_MIN_COVER:.0f} %' in notes[0]
