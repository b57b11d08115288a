"""Unit-test settings: Hypothesis draws the same examples on every run (derandomised), so a
CI run cannot pass or fail on the draw; ``HYPOTHESIS_PROFILE=explore`` draws fresh ones."""

from __future__ import annotations

import os

try:
    from hypothesis import settings
except ImportError:  # pragma: no cover - hypothesis is pinned in requirements.lock
    settings = None

if settings is not None:
    settings.register_profile('ci', derandomize=True, print_blob=True)
    settings.register_profile('explore', derandomize=False, print_blob=True)
    settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'ci'))
