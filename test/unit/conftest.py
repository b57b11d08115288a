"""Unit-test settings: Hypothesis draws the same examples on every run (derandomised), so a
CI run cannot pass or fail on the draw; ``HYPOTHESIS_PROFILE=explore`` draws fresh ones.
Fixtures several test files share."""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import pytest

try:
    from hypothesis import settings
except ImportError:  # pragma: no cover - hypothesis is pinned in requirements.lock
    settings = None

if settings is not None:
    settings.register_profile('ci', derandomize=True, print_blob=True)
    settings.register_profile('explore', derandomize=False, print_blob=True)
    settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'ci'))


@pytest.fixture
def kept(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Any]]:
    """The figures the plot functions close, kept open for the test (closed after it)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    real_close = plt.close
    got: list[Any] = []
    monkeypatch.setattr(plt, 'close', lambda fig=None: got.append(fig))
    yield got
    real_close('all')


@pytest.fixture(scope='session')
def resid_bench(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The residual tests' simulated bench bag (4 loads x 5 frequencies, 4 s walking, seed 1),
    its single-leg fit and its servos' temperature: five test files read their robot runs
    against the same bench, built once per process (each pytest-xdist worker runs whole
    files) instead of once per file. Read only: nothing may change the model."""
    from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
    from hexapod_bench_drivers.sim_bag import write_trace
    from hexapod_energy import residuals as R
    from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag

    path = tmp_path_factory.mktemp('resid_bench') / 'bench'
    plan = BenchPlan(loads_kg=(0.0, 0.187, 0.4, 0.6),
                     frequencies_hz=(0.0, 0.75, 1.25, 1.75, 2.25), walk_s=4.0)
    write_trace(simulate_bench(plan, seed=1), path)
    samples, _ = bench_phase_samples(read_bench_bag(path))
    return {'path': path, 'model': R.fit_bench_model(samples),
            'temp_ref_c': R._bench_temperature_c([path])}
