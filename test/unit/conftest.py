"""Unit-test settings: Hypothesis draws the same examples on every run (derandomised), so a
CI run cannot pass or fail on the draw; ``HYPOTHESIS_PROFILE=explore`` draws fresh ones."""

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
