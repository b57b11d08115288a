"""``hexapod-analyze``: offline analysis of bags into an output folder.

Subcommands (each documents its options with ``--help``):

- ``energy``    energetics of bench and robot bags (Brodoline et al. 2024) -> energy.json
- ``slip``      per-stance SLIP fits of RHex-class runs (Komsuoglu et al.) -> slip.json
- ``residuals`` model against measurement: residual, traced effects, before/after -> residuals.json
- ``report``    gather an output folder's JSON results and plots into report.html

Bags recorded under other topic names: ``hexapod-analyze --namespace /antbot energy ...`` reads
``/antbot/joint_states`` as ``/joint_states`` (and so on), ``--remap /power:=/battery_state``
renames one topic; both go before the command name and apply to every bag read.

Joint names outside the contract (``L1..Lk``/``R1..Rk`` legs, ``<leg>_hip``, ``<leg>_coxa``...):
``hexapod-analyze --joint-map hip_0:=L1_hip hip_1:=L2_hip ... slip BAG ...`` reads each recorded
name as its contract name (names not listed pass unchanged;
:mod:`hexapod_common.conversions`).

Motion capture broadcast as tf (no pose topic): ``hexapod-analyze --mocap-tf world:base_link
slip BAG ...`` reads that transform of ``/tf`` as ``/mocap/body`` (one hop: the transform as
recorded, no chain through other frames).

Several batteries on ``/battery_state`` (told apart by ``header.frame_id``, e.g. a servo pack
and a logic pack) are summed (:mod:`hexapod_common.battery`); ``hexapod-analyze
--battery-source servo energy ...`` keeps one of them instead.

Exit status, the same for every command: 0 done (``slip``: at least one bag analysed, the
refused ones listed in ``slip.json``); 2 input refused (a bad option, a missing or unreadable
bag, data that cannot be analysed), one line on stderr; 1 an unforeseen failure (a bug: one
line, ``HEXAPOD_DEBUG=1`` for the traceback); 130 interrupted.

Output folders: each command first sets aside (in a hidden folder in ``--out``) its own result
and figures of an earlier run (``energy.json`` with ``prediction.*``, ``four_quadrant_*`` ...;
``slip.json`` with ``fig7/8/9_*`` and ``slip_fit_*``; ``residuals.json`` with
``residual_*.png``), writes its figures, then its JSON last, then drops what it set aside;
an interrupted or failed run removes what it had written and puts the earlier result back,
so a folder never pairs one run's JSON with another run's figures, and a failed re-run does
not cost the last good result.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
from collections.abc import Sequence

from hexapod_common.bags import REMAP_ENV, parse_remap
from hexapod_common.battery import BATTERY_SOURCE_ENV
from hexapod_common.cli_args import NumberArgumentParser
from hexapod_common.errors import HexapodError
from hexapod_common.conversions import (
    JOINT_MAP_ENV,
    MOCAP_TF_ENV,
    parse_joint_map,
    parse_mocap_tf,
)

__all__ = ['build_parser', 'main']

#: subcommand -> module providing ``add_cli(subparsers)``
PROVIDERS = {
    'energy': 'hexapod_energy.cli',
    'slip': 'slip_identification.cli',
    'residuals': 'hexapod_energy.residuals_cli',
    'report': 'hexapod_common.report',
}


def build_parser() -> argparse.ArgumentParser:
    parser = NumberArgumentParser(
        prog='hexapod-analyze', description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--remap', action='extend', nargs=1, default=[], metavar='FROM:=TO',
                        help='read recorded topic FROM as TO (e.g. /robot/power:=/battery_state);'
                        ' before the command name; several FROM:=TO may follow')
    parser.add_argument('--namespace', default='', metavar='NS',
                        help='strip this prefix from recorded topics (a bag recorded under '
                        '/antbot/joint_states etc.); before the command name')
    parser.add_argument('--joint-map', action='extend', nargs=1, default=[],
                        metavar='FROM:=TO',
                        help='read recorded joint name FROM as the contract name TO (e.g. '
                        'hip_0:=L1_hip, j_c1_lf:=L1_coxa); before the command name; several '
                        'FROM:=TO may follow')
    parser.add_argument('--mocap-tf', default=None, metavar='PARENT:CHILD',
                        help='read the body pose from /tf: the transform PARENT -> CHILD (e.g. '
                        'world:base_link; a lab whose motion capture is broadcast as tf) as '
                        '/mocap/body; before the command name')
    parser.add_argument('--battery-source', default=None, metavar='ID',
                        help='keep only this battery of /battery_state (its header.frame_id, '
                        'else location or serial_number); default: several batteries are '
                        'summed; before the command name')
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


_MAPPING_OPTIONS = ('--remap', '--joint-map')
#: set to get the traceback of an unexpected failure instead of its one-line summary
DEBUG_ENV = 'HEXAPOD_DEBUG'


def _spell_out_mappings(argv: Sequence[str]) -> list[str]:
    """``--remap A:=B C:=D energy ...`` -> ``--remap A:=B --remap C:=D energy ...``.

    The mapping options take any number of FROM:=TO items; a greedy ``nargs='+'`` would also
    swallow the command name and its arguments, so the items (tokens holding ``:=``) are
    spelled out one option each before parsing. A malformed first item is kept for the option
    to refuse.
    """
    out: list[str] = []
    items = iter(list(argv))
    for tok in items:
        if tok not in _MAPPING_OPTIONS:
            out.append(tok)
            continue
        first = next(items, None)
        if first is None:
            out.append(tok)
            break
        out += [tok, first]
        for nxt in items:
            if ':=' in nxt and not nxt.startswith('-'):
                out += [tok, nxt]
            else:
                out.append(nxt)
                break
    return out


_GLOBAL_OPTIONS = ('--remap', '--namespace', '--joint-map', '--mocap-tf', '--battery-source')


def _misplaced_global(argv: Sequence[str]) -> str:
    """A global option given after the command name ('' when none): argparse said only
    'unrecognized arguments' (new-user review)."""
    cmd = next((i for i, a in enumerate(argv) if a in PROVIDERS), None)
    if cmd is None:
        return ''
    for a in argv[cmd + 1:]:
        opt = a.split('=', 1)[0]
        if opt in _GLOBAL_OPTIONS:
            return (f'{opt} goes before the command name: hexapod-analyze {opt} ... '
                    f'{argv[cmd]} ...')
    for a in argv[:cmd]:
        # a command's option before its name read "invalid choice: 'o_e7'" (a review)
        opt = a.split('=', 1)[0]
        if opt.startswith('--') and opt not in _GLOBAL_OPTIONS and opt != '--help':
            return (f'{opt} is an option of the command: it goes after the command name: '
                    f'hexapod-analyze {argv[cmd]} ... {opt} ...')
    return ''


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    raw = list(sys.argv[1:] if argv is None else argv)
    if why := _misplaced_global(raw):
        parser.error(why)
    args = parser.parse_args(_spell_out_mappings(raw))
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    if why := _repeated_bags(args):
        parser.error(why)
    saved = {k: os.environ.get(k)
             for k in (REMAP_ENV, JOINT_MAP_ENV, BATTERY_SOURCE_ENV, MOCAP_TF_ENV)}
    if args.battery_source is not None:
        os.environ[BATTERY_SOURCE_ENV] = args.battery_source
    if args.remap or args.namespace or args.mocap_tf:
        for warning in _unmatched_topic_mappings(args):
            print(f'hexapod-analyze: warning: {warning}', file=sys.stderr)
    if args.remap or args.namespace or args.mocap_tf:
        # every bag reader of this process and of its workers (--jobs) reads the contract names
        try:
            remap = parse_remap(args.remap)
            if args.mocap_tf:
                parse_mocap_tf(args.mocap_tf)
                remap.setdefault('/tf', '/mocap/body')
        except ValueError as err:
            parser.error(str(err))
        os.environ[REMAP_ENV] = json.dumps({'remap': remap, 'namespace': args.namespace})
        if args.mocap_tf:
            os.environ[MOCAP_TF_ENV] = args.mocap_tf
    if args.joint_map:
        try:
            joint_map = parse_joint_map(args.joint_map)
        except ValueError as err:
            parser.error(str(err))
        for warning in _unmatched_joint_mappings(args, joint_map):
            print(f'hexapod-analyze: warning: {warning}', file=sys.stderr)
        os.environ[JOINT_MAP_ENV] = json.dumps(joint_map)
    try:
        return _run(args)
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def _bag_paths(args: argparse.Namespace) -> list[str]:
    """The command's arguments that name existing bags (folders or .bag/.mcap/.db3 files)."""
    out: list[str] = []
    for key, value in vars(args).items():
        if key in ('out', 'func', 'command'):
            continue
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, str) and os.path.exists(v) and (
                    os.path.isdir(v) or v.endswith(('.bag', '.mcap', '.db3'))):
                out.append(v)
    return out


def _repeated_bags(args: argparse.Namespace) -> str:
    """Why the command names one bag twice ('' when it does not): the same folder or file
    (``run1`` and ``run1/``, a link), or a folder and a file of it.  Such a bag was analysed
    twice without a word: the prediction error over 3 runs for 2, a slip table of 16 stances
    from 8 (an outside review)."""
    for key, value in vars(args).items():
        if key in ('out', 'func', 'command') or not isinstance(value, list):
            continue
        # within one option: a bag under two options is for the command to refuse, with
        # its own reason (review D: '--robot X --slip X' hid 'not both')
        sub = argparse.Namespace(**{key: value})
        if why := _repeated_in(_bag_paths(sub)):
            return why
    return ''


def _repeated_in(paths: list[str]) -> str:
    seen: dict[str, str] = {}
    for path in paths:
        real = os.path.realpath(path)
        for other_real, other in seen.items():
            inside = (real.startswith(other_real + os.sep)
                      or other_real.startswith(real + os.sep))
            if real == other_real or inside:
                return (f'the bag {other!r} is given twice ({path!r}' +
                        (', a file of the other' if inside else '') +
                        '): each bag once, please')
        seen[real] = path
    return ''


def _unmatched_joint_mappings(args: argparse.Namespace, joint_map: dict[str, str]
                              ) -> list[str]:
    """Warnings for a ``--joint-map`` source no given bag records on ``/joint_states`` (a
    typo), and for a target name a bag records already (two joints would share it): both ran
    without a word (outside review). The first 200 joint messages of each bag are read."""
    from hexapod_common.bags import iter_messages, open_reader

    names: set[str] = set()
    for path in _bag_paths(args):
        try:
            with open_reader(path) as reader:
                for k, m in enumerate(iter_messages(reader, ['/joint_states'])):
                    names.update(str(n) for n in reader.deserialize(m.data, m.msgtype).name)
                    if k >= 200:
                        break
        except Exception:   # noqa: BLE001 - the command names an unreadable bag itself
            continue
    if not names:
        return []
    out = []
    for src, dst in sorted(joint_map.items()):
        if src not in names:
            out.append(f'--joint-map {src}:={dst}: no given bag records a joint {src} on '
                       '/joint_states')
        elif dst in names and dst not in joint_map:
            out.append(f'--joint-map {src}:={dst}: the bags record a joint {dst} already: two '
                       'joints would share the name')
    return out


def _unmatched_topic_mappings(args: argparse.Namespace) -> list[str]:
    """Warnings for a ``--remap`` source, ``--namespace`` or ``--mocap-tf`` that no given bag
    has (a typo was silent: the analysis then refused the bag for a topic it does have, or
    ran without motion capture; new-user review)."""
    from hexapod_common.bags import open_reader

    topics: set[str] = set()
    paths = _bag_paths(args)
    for path in paths:
        try:
            with open_reader(path, remap={}, namespace='') as reader:
                topics |= {c.topic for c in reader.connections}
        except Exception:   # noqa: BLE001 - the command names an unreadable bag itself
            continue
    if not topics:
        return []
    out = []
    try:
        remap = parse_remap(args.remap)
    except ValueError:
        remap = {}
    for src in sorted(remap):
        if src not in topics:
            out.append(f'--remap {src}:={remap[src]}: no given bag has {src}')
    ns = '/' + args.namespace.strip('/') if args.namespace.strip('/') else ''
    if ns and not any(t.startswith(ns + '/') for t in topics):
        out.append(f'--namespace {args.namespace}: no topic of the given bags starts with {ns}/')
    if args.mocap_tf and '/tf' not in topics:
        out.append(f'--mocap-tf {args.mocap_tf}: no given bag has /tf')
    return out


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        # the commands write their JSON last and remove the figures of an unfinished run
        # (hexapod_common.outdir): 'nothing more written' sat beside a complete-looking one
        print(f'hexapod-analyze {args.command}: interrupted; no result written',
              file=sys.stderr)
        return 130
    except (OSError, ValueError, LookupError, RuntimeError, HexapodError) as err:
        # typed errors of the analysis (input refused): one line, no traceback, exit 2
        print(f'hexapod-analyze {args.command}: error: {err}', file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 - a bug or an input nobody foresaw
        if os.environ.get(DEBUG_ENV):
            raise
        print(f'hexapod-analyze {args.command}: failed: {type(err).__name__}: {err} (set '
              f'{DEBUG_ENV}=1 for the traceback, and please report it with the bag)',
              file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
