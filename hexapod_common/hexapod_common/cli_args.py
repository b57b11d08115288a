"""An argparse parser that reads ``-1e9`` and ``-inf`` as numbers, not as options.

Python 3.11's argparse takes a token for a negative number only when it matches
``-123`` or ``-1.5``: ``--offset -1e-3`` or ``--box -1e9 ...`` was refused with "expected one
argument", so a value written in scientific notation could not be negative. The parsers of
every command use this class (subparsers inherit it through ``add_subparsers``).
"""
from __future__ import annotations

import argparse
import re

__all__ = ['NumberArgumentParser', 'NEGATIVE_NUMBER']

#: a negative decimal, scientific or non-finite number (an option never looks like one)
NEGATIVE_NUMBER = re.compile(r'^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$',
                             re.IGNORECASE)


class NumberArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose negative numbers include ``-1e9``, ``-2.5E-3``."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER
