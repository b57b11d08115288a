"""Force sensor: line parser (malformed lines counted, never raised), calibration, pty source."""

from __future__ import annotations

import os
import tty

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.force_backend import (
    ForceCalibration,
    ForceLineParser,
    ForceReading,
    SerialForceSource,
)

MALFORMED = [b'12,abc\n', b'no comma\n', b'1,2,3\n', b'\xff\xfe,1\n', b'-5,100\n', b',\n',
             b'9' * 100 + b'\n']


def test_parser_good_comment_and_malformed_lines():
    p = ForceLineParser()
    data = b'# HX711 ready\r\n1000,-12345\r\n' + b''.join(MALFORMED) + b'1010,200\n\n'
    out = []
    for k in range(0, len(data), 7):            # arbitrary chunking across line boundaries
        out += p.feed(data[k:k + 7])
    assert out == [ForceReading(1.0, -12345), ForceReading(1.01, 200)]
    assert (p.lines_ok, p.malformed, p.comments) == (2, len(MALFORMED), 1)


def test_parser_runaway_line_without_newline():
    p = ForceLineParser()
    assert p.feed(b'7' * 300) == []
    assert p.feed(b'77\n5,6\n') == [ForceReading(0.005, 6)]
    assert p.malformed == 1


def test_calibration_recovers_coefficients():
    rng = np.random.default_rng(4)
    true = np.array([-1.5, 2.0e-4, 12.0, -4.0])       # N, N/count, N/m, N/m
    n = 60
    tip_x = rng.uniform(-0.05, 0.05, n)
    tip_y = rng.uniform(0.10, 0.20, n)
    force = rng.choice([0.0, 0.93, 1.38, 1.83, 5.05], n)   # the bench weights x g
    raw = (force - true[0] - true[2] * tip_x - true[3] * tip_y) / true[1]
    raw = raw + rng.normal(0, 20, n)                       # ADC noise
    cal = ForceCalibration().fit(raw, tip_x, tip_y, force)
    assert_allclose(cal.coef_, true, rtol=0.03, atol=0.05)
    assert np.all(np.abs(cal.coef_ - true) < 5 * cal.coef_stderr_ + 1e-9)
    assert_allclose(cal.predict(raw, tip_x, tip_y), force, atol=0.02)
    with pytest.raises(ValueError, match='must each vary'):
        ForceCalibration().fit(raw, 0.0, 0.0, force)


@pytest.mark.timeout(30)
def test_serial_source_on_pty():
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        src = SerialForceSource(os.ttyname(slave))
        os.write(master, b'# boot\n100,5\n1x0,5\n110,')
        got = []
        while len(got) < 1:
            got += src.poll()
        os.write(master, b'7\n')
        while len(got) < 2:
            got += src.poll()
        assert got == [ForceReading(0.1, 5), ForceReading(0.11, 7)]
        assert src.parser.malformed == 1
        src.close()
    finally:
        os.close(master)
        os.close(slave)
