"""An outside review of the live slip_fitter's self-calibration (slip_identification.calibration)
on synthetic samples (hips turning at 1 stride/s, motion capture at 100 Hz; the estimators
replaced by stand-ins, so each test runs in well under a second): stopping the node while the
worker ran, the worker ran on for seconds, then called ``on_ready`` on the destroyed node's
guard condition (an InvalidHandle traceback in the thread); ``close`` stops it and keeps the
result of a worker already done.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from hexapod_common.conversions import JointStateSample
from slip_identification.calibration import Calibration, SelfCalibration
from slip_identification.online import OnlineSlip

NAMES = tuple(f'{side}{k}_hip' for side in 'LR' for k in (1, 2, 3))
W = 2.0 * math.pi   # hips' speed [rad/s]: a stride of 1 s
INSIDE = np.array([0.0, 0.0, 0.1])
OUTSIDE = np.array([0.0, 3.0, 0.1])   # beyond the default box's y of +-0.5 m
Q = np.array([0.0, 0.0, 0.0, 1.0])


def _feed(cal: SelfCalibration, t0: float, t1: float, position: np.ndarray) -> None:
    """Joint states and motion capture at 100 Hz from ``t0`` to ``t1``."""
    for k in range(int(round((t1 - t0) * 100))):
        t = t0 + k / 100.0
        cal.offer('js', JointStateSample(t, NAMES, np.full(6, W * t), np.full(6, W),
                                         np.zeros(6)))
        cal.offer('mocap', t, position, Q)


class _Estimators:
    """A stand-in for the estimators: records the runs, optionally blocks until released."""

    def __init__(self, block: bool = False) -> None:
        self.runs: list[Any] = []
        self.go = threading.Event()
        if not block:
            self.go.set()
        self.cores = 0

    def calibrate(self, run: Any) -> Calibration:
        self.runs.append(run)
        assert self.go.wait(30.0)
        return Calibration(refused='a stand-in')

    def core(self, cal: Calibration) -> OnlineSlip:
        self.cores += 1
        return OnlineSlip()


def test_close_stops_a_running_worker_without_waking_the_node():
    est = _Estimators(block=True)
    woken: list[int] = []
    cal = SelfCalibration(1.0, est.calibrate, est.core, on_ready=lambda: woken.append(1))
    errors: list[Any] = []
    hook, threading.excepthook = threading.excepthook, errors.append
    try:
        _feed(cal, 0.0, 1.5, INSIDE)
        assert cal.state == 'calibrating'
        assert cal.close() is False     # not ready: nothing to take
        est.go.set()
        assert cal.wait(30.0)
    finally:
        threading.excepthook = hook
    assert not errors and not woken     # before: on_ready called after the node was gone
    assert est.cores == 0               # and the buffer not replayed for nobody
    assert cal.take() is None


def test_close_keeps_the_result_of_a_worker_already_done():
    est = _Estimators()
    woken: list[int] = []
    cal = SelfCalibration(1.0, est.calibrate, est.core, on_ready=lambda: woken.append(1))
    _feed(cal, 0.0, 1.5, INSIDE)
    assert cal.wait(30.0) and woken == [1]
    assert cal.close() is True
    got = cal.take()
    assert got is not None and got[1].refused == 'a stand-in'
