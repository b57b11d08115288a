"""``hexapod-analyze``: offline analysis of bags into an output folder.

Subcommands (each documents its options with ``--help``):

- ``energy``    energetics of bench and robot bags (Brodoline et al. 2024) -> energy.json
- ``slip``      per-stance SLIP fits of RHex-class runs (Komsuoglu et al.) -> slip.json
- ``residuals`` model against measurement: residual, traced effects, before/after -> residuals.json
- ``report``    gather an output folder's JSON results and plots into report.html

Bags recorded under other topic names: ``hexapod-analyze --namespace /antbot energy ...`` reads
``/antbot/joint_states`` as ``/joint_states`` (and so on), ``--remap /power:=/battery_state``
renames one topic; both go before the command name and apply to every bag read.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
from collections.abc import Sequence

from hexapod_common.bags import REMAP_ENV, parse_remap

__all__ = ['build_parser', 'main']

#: subcommand -> module providing ``add_cli(subparsers)``
PROVIDERS = {
    'energy': 'hexapod_energy.cli',
    'slip': 'slip_identification.cli',
    'residuals': 'hexapod_energy.residuals_cli',
    'report': 'hexapod_common.report',
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='hexapod-analyze', description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--remap', nargs='+', default=[], metavar='FROM:=TO',
                        help='read recorded topic FROM as TO (e.g. /robot/power:=/battery_state);'
                        ' before the command name')
    parser.add_argument('--namespace', default='', metavar='NS',
                        help='strip this prefix from recorded topics (a bag recorded under '
                        '/antbot/joint_states etc.); before the command name')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name, module in PROVIDERS.items():
        try:
            importlib.import_module(module).add_cli(sub)
        except ImportError as err:  # a broken install should not hide the other commands
            p = sub.add_parser(name, help=f'(unavailable: {err})')
            p.set_defaults(func=lambda _args, _e=err: _unavailable(_e))
    return parser


def _unavailable(err: Exception) -> int:
    print(f'hexapod-analyze: error: this command is unavailable: {err}', file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    saved = os.environ.get(REMAP_ENV)
    if args.remap or args.namespace:
        # every bag reader of this process and of its workers (--jobs) reads the contract names
        try:
            remap = parse_remap(args.remap)
        except ValueError as err:
            parser.error(str(err))
        os.environ[REMAP_ENV] = json.dumps({'remap': remap, 'namespace': args.namespace})
    try:
        return _run(args)
    finally:
        if saved is None:
            os.environ.pop(REMAP_ENV, None)
        else:
            os.environ[REMAP_ENV] = saved


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (OSError, ValueError, LookupError, RuntimeError) as err:
        # typed errors of the analysis: one line, no traceback
        print(f'hexapod-analyze {args.command}: error: {err}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
