import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

#: seconds a test without its own ``@pytest.mark.timeout`` may run (pytest-timeout): a node
#: that spins for ever (a console script that should have refused its parameters and started
#: instead) fails its test instead of holding the suite's lane until CI is stopped
DEFAULT_TIMEOUT_S = 600


def pytest_collection_modifyitems(items):
    for item in items:
        if item.get_closest_marker('timeout') is None:
            item.add_marker(pytest.mark.timeout(DEFAULT_TIMEOUT_S))
