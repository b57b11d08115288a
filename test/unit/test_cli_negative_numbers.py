"""Negative values in scientific notation are values, not options (every command's parser).

Python 3.11's argparse read ``-1e9`` or ``-2.5e-3`` as an unknown option: ``--offset -2.5e-3``
gave "expected one argument" and a 6-number ``--box`` could not hold ``-1e9``.
"""
import argparse

import pytest

from hexapod_common import analyze_cli
from hexapod_common.cli_args import NEGATIVE_NUMBER, NumberArgumentParser
from hexapod_bench_drivers import sim_cli


@pytest.mark.parametrize('tok', ['-1e9', '-2.5e-3', '-1E+3', '-.5', '-3', '-0.25', '-inf',
                                 '-nan', '-Infinity'])
def test_negative_numbers_match(tok):
    assert NEGATIVE_NUMBER.match(tok)


@pytest.mark.parametrize('tok', ['-e9', '--box', '-x', '-1e', '-1e9x', '-h', '-1.2.3'])
def test_options_do_not_match(tok):
    assert not NEGATIVE_NUMBER.match(tok)


def test_plain_argparse_refuses_what_ours_reads():
    for cls, ok in ((argparse.ArgumentParser, False), (NumberArgumentParser, True)):
        p = cls(exit_on_error=False)
        p.add_argument('--offset', type=float)
        if ok:
            assert p.parse_args(['--offset', '-2.5e-3']).offset == -2.5e-3
        else:
            with pytest.raises((argparse.ArgumentError, SystemExit)):
                p.parse_args(['--offset', '-2.5e-3'])


def test_analyze_subcommands_read_scientific_negatives():
    parser = analyze_cli.build_parser()
    args = parser.parse_args(['slip', 'bag', '--out', 'o', '--box', '-1e9', '-2e-1', '0',
                              '1e9', '1', '1', '--offset-lag', '-1e-3'])
    assert args.box == [-1e9, -0.2, 0.0, 1e9, 1.0, 1.0]
    assert args.offset_lag == -1e-3
    args = parser.parse_args(['energy', '--robot', 'run', '--out', 'o',
                              '--limits', '-1e9', '0.2', '0.3'])
    assert args.limits == [-1e9, 0.2, 0.3]


def test_sim_reads_scientific_negatives():
    args = sim_cli.build_parser().parse_args(['robot', '--out', 'o', '--rate', '-1e2'])
    assert args.rate == -100.0


def test_an_option_after_an_option_is_still_an_option():
    parser = analyze_cli.build_parser()
    with pytest.raises(SystemExit):
        parser.parse_args(['slip', 'bag', '--offset-lag', '--box'])
