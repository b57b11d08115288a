"""rosbag2 bags through rosbags: the project's typestore, a crash-safe writer, a reader.

- :func:`typestore` is the ROS 2 Jazzy typestore plus ``hexapod_interfaces`` registered from the
  ``.msg`` text, so bags written here carry full message definitions and read anywhere.
- :class:`BagWriter` writes an ordinary rosbag2 bag (mcap by default, sqlite3 on request). With
  ``split_every_s`` it closes a storage file every so many seconds and rewrites
  ``metadata.yaml`` atomically, so a killed recorder loses at most the open split.
- :func:`open_reader` opens bags written by any tool, with a one-line typed error on bad input.
  Bags recorded under other topic names (another lab's namespace, a renamed topic) are read
  through a topic remapping: ``open_reader(path, remap={'/antbot/joint_states':
  '/joint_states'}, namespace='/antbot')``, or for every reader of the process through the
  environment variable ``HEXAPOD_BAG_REMAP`` (JSON ``{"remap": {...}, "namespace": "..."}``,
  set by ``hexapod-analyze --remap FROM:=TO --namespace NS``), so analyses see the contract
  names of DESIGN section 4.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, fields as dataclass_fields
from functools import lru_cache
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader
from rosbags.highlevel.anyreader import AnyReaderError
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from ruamel.yaml import YAML

from hexapod_common.conversions import MOCAP_TF_ENV, parse_mocap_tf, pick_transform
from hexapod_common.errors import (
    BagExistsError,
    BagNotFoundError,
    BagReadError,
    UnknownTypeError,
)

__all__ = [
    'BagMessage',
    'BagWriter',
    'CUSTOM_MSGS',
    'SampleColumns',
    'duplicates_note',
    'find_msg_dir',
    'iter_messages',
    'message_progress',
    'new_msg',
    'OpenedReader',
    'open_reader',
    'REMAP_ENV',
    'parse_remap',
    'stamp',
    'typestore',
]

CUSTOM_MSGS = ('GaitPhase', 'ServoStatus', 'BenchSession', 'EnergeticDescriptors', 'SlipFit')
_PKG = 'hexapod_interfaces'


def find_msg_dir() -> Path:
    """The folder holding ``hexapod_interfaces``'s ``.msg`` files (installed or in the source)."""
    candidates = [Path(p) / 'share' / _PKG / 'msg'
                  for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    candidates.append(Path(sys.prefix) / 'share' / _PKG / 'msg')
    candidates.append(Path(__file__).resolve().parents[2] / 'src' / _PKG / 'msg')
    for cand in candidates:
        if (cand / 'GaitPhase.msg').is_file():
            return cand
    raise UnknownTypeError(
        f'cannot find {_PKG} .msg files; looked in: ' + ', '.join(str(c) for c in candidates))


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """ROS 2 Jazzy types plus ``hexapod_interfaces/msg/*``."""
    store = get_typestore(Stores.ROS2_JAZZY)
    msg_dir = find_msg_dir()
    types: dict[str, Any] = {}
    for name in CUSTOM_MSGS:
        text = (msg_dir / f'{name}.msg').read_text(encoding='utf-8')
        types.update(get_types_from_msg(text, f'{_PKG}/msg/{name}'))
    store.register(types)
    return store


_NUMPY_DTYPES = {
    'bool': 'bool', 'byte': 'uint8', 'char': 'uint8', 'int8': 'int8', 'uint8': 'uint8',
    'int16': 'int16', 'uint16': 'uint16', 'int32': 'int32', 'uint32': 'uint32',
    'int64': 'int64', 'uint64': 'uint64', 'float32': 'float32', 'float64': 'float64',
}


def _default_value(store: Typestore, node: tuple[Any, Any]) -> Any:
    import numpy as np

    kind, detail = node
    kind = int(kind)
    if kind == 1:  # base type
        name = detail[0]
        if name == 'string':
            return ''
        if name == 'bool':
            return False
        return 0.0 if name.startswith('float') else 0
    if kind == 2:  # nested message
        return new_msg(detail, store=store)
    inner, length = detail
    if int(inner[0]) == 1 and inner[1][0] in _NUMPY_DTYPES:
        return np.zeros(length if kind == 3 else 0, dtype=_NUMPY_DTYPES[inner[1][0]])
    return [_default_value(store, inner) for _ in range(length if kind == 3 else 0)]


def new_msg(msgtype: str, *, store: Typestore | None = None, **fields: Any) -> Any:
    """A rosbags message of ``msgtype`` with ROS defaults for every field not given.

    Numeric sequences given as lists are converted to numpy arrays of the field's dtype.
    """
    import numpy as np

    store = store or typestore()
    if msgtype not in store.fielddefs:
        raise UnknownTypeError(f'message type {msgtype!r} is not in the typestore')
    values = {}
    for name, node in store.fielddefs[msgtype][1]:
        if name in fields:
            value = fields.pop(name)
            kind, detail = int(node[0]), node[1]
            if kind in (3, 4) and int(detail[0][0]) == 1 and detail[0][1][0] in _NUMPY_DTYPES:
                value = np.asarray(value, dtype=_NUMPY_DTYPES[detail[0][1][0]])
            values[name] = value
        else:
            values[name] = _default_value(store, node)
    if fields:
        raise TypeError(f'{msgtype} has no field(s) {sorted(fields)}')
    return store.types[msgtype](**values)


def stamp(t_ns: int, frame_id: str = '', *, store: Typestore | None = None) -> Any:
    """A rosbags ``std_msgs/Header`` for bag time ``t_ns``."""
    store = store or typestore()
    time_t = store.types['builtin_interfaces/msg/Time']
    return store.types['std_msgs/msg/Header'](
        stamp=time_t(sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000)),
        frame_id=frame_id)


class BagWriter:
    """Write a rosbag2 bag with full message definitions.

    Parameters
    ----------
    path
        Bag folder to create; an existing path is refused (nothing is overwritten).
    storage
        ``'mcap'`` (default) or ``'sqlite3'``.
    split_every_s
        If set, close the current storage file after this many seconds of wall-clock time and
        start the next; ``metadata.yaml`` always describes every closed file.

    Messages are given either as rosbags message instances (serialised here) or as CDR bytes.
    """

    def __init__(self, path: str | os.PathLike[str], *, storage: str = 'mcap',
                 split_every_s: float | None = None, store: Typestore | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagExistsError(f'refusing to overwrite existing bag: {self.path}')
        if storage not in ('mcap', 'sqlite3'):
            raise ValueError(f'storage must be mcap or sqlite3, got {storage!r}')
        self.storage = storage
        self.split_every_s = split_every_s
        self.types = store or typestore()
        self._plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
        self._conns: dict[tuple[str, str], Any] = {}  # (topic, type) -> connection of the split
        self._topics: dict[tuple[str, str], dict[str, Any]] = {}  # add_connection kwargs
        self._custom: dict[str, str] = {}
        self._writer: Writer | None = None
        self._split_index = 0
        self._split_started = 0.0
        self._merged: dict[str, Any] | None = None
        self._merged_index = -1            # the last split merged into the bag's metadata
        self._in_memory_index = -1         # ... into _merged (its metadata.yaml maybe not yet)
        self._files_json: list[str] = []   # each split's files entry, serialised once
        self.counts: dict[str, int] = {}
        self.path.mkdir(parents=True)

    # -- context manager -------------------------------------------------------------------
    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- public API ------------------------------------------------------------------------
    def set_custom_data(self, key: str, value: str) -> None:
        """Store ``key: value`` in the bag's metadata (``custom_data``)."""
        self._custom[key] = value
        if self._writer is not None:
            self._writer.set_custom_data(key, value)

    def add_topic(self, topic: str, msgtype: str, *, msgdef: str | None = None,
                  rihs01: str | None = None) -> None:
        """Declare a topic (done implicitly by :meth:`write`)."""
        key = (topic, msgtype)
        if key in self._topics:
            return
        if msgdef is None:
            if msgtype not in self.types.fielddefs:
                raise UnknownTypeError(f'message type {msgtype!r} is not in the typestore')
            kwargs: dict[str, Any] = {'typestore': self.types}
        else:
            kwargs = {'msgdef': msgdef, 'rihs01': rihs01}
        self._topics[key] = kwargs
        if self._writer is not None:
            self._conns[key] = self._writer.add_connection(topic, msgtype, **kwargs)

    def write(self, topic: str, msgtype: str, msg: Any, stamp_ns: int) -> None:
        """Write one message (rosbags instance or CDR bytes) at ``stamp_ns``."""
        self.add_topic(topic, msgtype)
        writer = self._ensure_writer()
        data = msg if isinstance(msg, (bytes, bytearray, memoryview)) else \
            self.types.serialize_cdr(msg, msgtype)
        writer.write(self._conns[(topic, msgtype)], int(stamp_ns), data)
        self.counts[topic] = self.counts.get(topic, 0) + 1
        if self.split_every_s is not None and \
                time.monotonic() - self._split_started >= self.split_every_s:
            self.flush()

    def flush(self) -> None:
        """Close the open split so that everything written so far is durable (also one whose
        close was interrupted: see :meth:`close`)."""
        if self._writer is not None or self._tmp_split().exists():
            self._close_split()

    def close(self) -> None:
        """Close the bag; an empty bag still gets valid metadata.

        Called again after an interruption (a ``KeyboardInterrupt`` from a second Ctrl-C), it
        finishes the split whose close was cut short: it used to open ``.split_N`` again
        (``WriterError: exists already``, no ``metadata.yaml``, the last split's data left
        in the hidden folder; an outside review)."""
        if self._writer is None and self._merged is None and not self._tmp_split().exists():
            self._ensure_writer()
        self.flush()

    # -- splits ----------------------------------------------------------------------------
    def _tmp_split(self) -> Path:
        return self.path / f'.split_{self._split_index}'

    def _ensure_writer(self) -> Writer:
        if self._writer is None:
            writer = Writer(self._tmp_split(), version=9, storage_plugin=self._plugin)
            writer.open()
            for key, value in self._custom.items():
                writer.set_custom_data(key, value)
            self._conns = {key: writer.add_connection(key[0], key[1], **kw)
                           for key, kw in self._topics.items()}
            self._writer = writer
            self._split_started = time.monotonic()
        return self._writer

    def _close_split(self) -> None:
        """Close split ``_split_index`` into the bag. Each step can be run again after an
        interruption: the writer is forgotten once closed, the split's file is moved once,
        merged once (``_merged_index``), and the hidden folder removed last."""
        tmp = self._tmp_split()
        if self._writer is not None:
            if self._writer.storage is not None:   # None: closed, only forgetting it was cut
                self._writer.close()
            self._writer = None
        if self._merged_index < self._split_index:
            yaml = YAML(typ='safe')
            meta = yaml.load((tmp / 'metadata.yaml').read_text(encoding='utf8'))
            info = meta['rosbag2_bagfile_information']
            single = info['relative_file_paths'][0]
            final = f'{self.path.name}_{self._split_index}{Path(single).suffix}'
            if (tmp / single).exists():
                (tmp / single).replace(self.path / final)
            info['relative_file_paths'] = [final]
            info['files'][0]['path'] = final
            self._merge(info, self._split_index)
            self._merged_index = self._split_index
        shutil.rmtree(tmp, ignore_errors=True)
        self._split_index += 1

    def _merge(self, info: dict[str, Any], index: int) -> None:
        """Merge split ``index``'s ``info`` into the bag's metadata (once: run again after an
        interrupted metadata write, it only writes; it merged the split twice, 15 messages
        counted for 10 written: review J5) and write ``metadata.yaml``."""
        if self._in_memory_index < index:
            self._merged = info if self._merged is None else _merge_info(self._merged, info)
            self._files_json.extend(json.dumps(f) for f in info['files'])
            self._in_memory_index = index
        assert self._merged is not None
        self._merged['custom_data'] = dict(self._custom) or None
        self._merged['ros_distro'] = 'jazzy'
        # JSON is YAML (rosbags, ros2 bag and yaml-cpp read it): ruamel's dump of every
        # split's entry took 0.4 ms per split, so a recorder closing a split every second
        # spent 0.85 s per flush after 2,000 splits and fell behind (an outside review: from
        # 22 min on it recorded 2 of 1,200 msg/s); json.dumps of the same is ~100x faster
        # the files' entries are serialised once each and spliced in
        head = dict(self._merged, files='@FILES@', relative_file_paths='@PATHS@')
        text = json.dumps({'rosbag2_bagfile_information': head}, indent=1)
        text = text.replace('"@FILES@"', '[' + ',\n  '.join(self._files_json) + ']', 1)
        text = text.replace('"@PATHS@"', json.dumps(self._merged['relative_file_paths']), 1)
        tmp_meta = self.path / 'metadata.yaml.tmp'
        tmp_meta.write_text(text + '\n', encoding='utf8')
        tmp_meta.replace(self.path / 'metadata.yaml')


def _merge_info(old: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """Metadata of two consecutive splits as one bag: ``old`` (the bag so far, owned by the
    writer) extended in place by ``new`` (one split), in time independent of the splits so
    far (it used to rebuild every list: quadratic over a long recording)."""
    files = list(new['files'])
    old_has = old['message_count'] > 0
    for f in files:
        if f['message_count'] <= 0:
            continue
        start = f['starting_time']['nanoseconds_since_epoch']
        end = start + f['duration']['nanoseconds']
        if old_has:
            o_start = old['starting_time']['nanoseconds_since_epoch']
            o_end = o_start + old['duration']['nanoseconds']
            start, end = min(start, o_start), max(end, o_end)
        old['starting_time'] = {'nanoseconds_since_epoch': start}
        old['duration'] = {'nanoseconds': end - start}
        old_has = True
    old['files'].extend(files)
    old['relative_file_paths'].extend(f['path'] for f in files)
    old['message_count'] += new['message_count']
    topics = {t['topic_metadata']['name']: t for t in old['topics_with_message_count']}
    for t in new['topics_with_message_count']:
        name = t['topic_metadata']['name']
        if name in topics:
            topics[name]['message_count'] += t['message_count']
        else:
            old['topics_with_message_count'].append(dict(t))
            topics[name] = old['topics_with_message_count'][-1]
    return old


#: Environment variable holding a process-wide topic remapping for :func:`open_reader` (JSON).
REMAP_ENV = 'HEXAPOD_BAG_REMAP'


def parse_remap(items: Sequence[str]) -> dict[str, str]:
    """``['FROM:=TO', ...]`` -> ``{FROM: TO}`` (recorded topic -> topic the analysis reads).

    Raises :class:`ValueError` naming the bad item.
    """
    out: dict[str, str] = {}
    for item in items:
        src, sep, dst = item.partition(':=')
        if not sep or not src.strip() or not dst.strip():
            raise ValueError(f'a topic remap is FROM:=TO (recorded topic := analysed topic), '
                             f'got {item!r}')
        out['/' + src.strip().lstrip('/')] = '/' + dst.strip().lstrip('/')
    return out


def _remap_from_env() -> tuple[dict[str, str], str]:
    raw = os.environ.get(REMAP_ENV, '').strip()
    if not raw:
        return {}, ''
    try:
        doc = json.loads(raw)
        return {str(k): str(v) for k, v in dict(doc.get('remap', {})).items()}, \
            str(doc.get('namespace', '') or '')
    except (ValueError, TypeError, AttributeError) as err:
        raise BagReadError(f'{REMAP_ENV} is not JSON {{"remap": {{...}}, "namespace": ...}}: '
                           f'{err}') from err


_REINDEX = '`ros2 bag reindex BAG` rewrites metadata.yaml from the storage files'


def _fmt_qos_value(value: Any) -> str:
    if isinstance(value, tuple) and hasattr(value, 'nsec'):   # QosTime
        return f'{value.sec} s {value.nsec} ns'
    name = getattr(value, 'name', None)
    return name.lower() if isinstance(name, str) else str(value)


def _qos_difference(meta: Sequence[Any], stored: Sequence[Any]) -> str:
    """What differs between metadata.yaml's offered QoS profiles and the storage's."""
    if len(meta) != len(stored):
        return (f'offered QoS: {len(meta)} profile(s) in metadata.yaml, {len(stored)} in the '
                'storage')
    for k, (a, b) in enumerate(zip(meta, stored)):
        if a == b:
            continue
        names = getattr(a, '_fields', ())
        field = next((f for f in names if getattr(a, f) != getattr(b, f)), '')
        which = f' of profile {k + 1}' if len(meta) > 1 else ''
        if not field:
            return f'offered QoS{which}'
        return (f'offered QoS {field}{which}: {_fmt_qos_value(getattr(a, field))} in '
                f'metadata.yaml, {_fmt_qos_value(getattr(b, field))} in the storage')
    return 'offered QoS'


def _strict_match(meta: Any, stored: Any) -> bool:
    """rosbags' own rule (``DirectoryReader.messages``) pairing a storage connection with a
    metadata.yaml one; a storage connection paired with none yields no message."""
    return (meta.topic == stored.topic and meta.msgtype == stored.msgtype
            and meta.ext == stored.ext
            and (not stored.digest or not meta.digest or meta.digest == stored.digest))


def _canon(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return tuple(_canon(v) for v in value)
    return value


def _nested_types(node: Any) -> Iterator[str]:
    kind, detail = int(node[0]), node[1]
    if kind == 2:
        yield str(detail)
    elif kind in (3, 4):
        yield from _nested_types(detail[0])


def _field_difference(bag: dict[str, Any], store: Typestore, msgtype: str) -> str:
    """'' when ``msgtype`` and every type it holds have the same fields (names and types) in
    the bag's definitions ``bag`` as in ``store``; else what differs."""
    todo, seen = [msgtype], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        if name not in store.fielddefs:
            return f'{name} is not a ROS 2 Jazzy or {_PKG} type'
        if name not in bag:
            return f'the bag has no definition of {name}'
        ours, theirs = store.fielddefs[name][1], bag[name][1]
        if _canon(ours) != _canon(theirs):
            mine = [f[0] for f in ours]
            other = [f[0] for f in theirs]
            if mine != other:
                return f'{name} has fields {other} in the bag, {mine} in ROS 2 Jazzy'
            return f'{name}: field types differ from ROS 2 Jazzy\'s'
        for _, node in ours:
            todo.extend(_nested_types(node))
    return ''


class OpenedReader(AnyReader):
    """An AnyReader that is already open; ``with`` just closes it at the end.

    ``topic_alias`` maps recorded topic -> analysed topic for the connections renamed by
    :meth:`apply_remap` (``connections`` then carry the analysed names). ``notes`` lists how
    the input was read when it was not an ordinary bag (mcap files without metadata.yaml,
    metadata.yaml that disagrees with the storage, a type hash that is not its definition's).

    Opening a rosbag2 bag differs from ``AnyReader``'s in two ways (bags of other tools and
    distros):

    - a storage connection that rosbags pairs with no metadata.yaml topic (offered QoS, type
      hash or serialization written differently in metadata.yaml, e.g. regenerated by another
      tool or distro; rosbags then yields no message of the topic and raises nothing) is
      paired by topic and type, with a note. A topic that cannot be paired (another type in
      the storage, or in no storage file) is kept in ``unreadable`` and
      :func:`iter_messages` refuses it.
    - a stored type hash that is not the hash of the bag's definition of the type (rosbags:
      "hash mismatch", the whole bag refused) is accepted, with a note, when that definition
      has the same fields as this project's typestore (ROS 2 Jazzy plus ``hexapod_interfaces``);
      otherwise the error names the topics, both hashes and what differs.
    """

    topic_alias: dict[str, str]
    notes: list[str]
    #: recorded topic -> why its messages cannot be read (see :func:`iter_messages`)
    unreadable: dict[str, str]
    open_notes: list[str]
    #: temporary directories of salvaged mcap files (:func:`salvage_mcap`), removed on close
    salvage_dirs: list[Path] = []

    def close(self) -> None:
        try:
            super().close()
        finally:
            for d in self.salvage_dirs:
                shutil.rmtree(d, ignore_errors=True)

    def deserialize(self, rawdata: bytes, typename: str) -> Any:
        """AnyReader.deserialize; bytes that do not decode as ``typename`` raise
        :class:`BagReadError` naming the type (input refused, exit 2). rosbags raises its own
        AnyReaderError, which the commands took for a bug: "failed: ... please report it",
        exit 1 (an outside review damaged 64 bytes inside a message of a robot bag)."""
        try:
            return super().deserialize(rawdata, typename)
        except Exception as err:  # noqa: BLE001 - rosbags raises several types for bad bytes
            msg = str(err).splitlines()[0] if str(err) else type(err).__name__
            where = ', '.join(str(p) for p in getattr(self, 'paths', ()))
            raise BagReadError(
                f'bag {where}: a {typename} message ({len(rawdata)} bytes) cannot be decoded '
                f'({msg}): the bag is corrupt') from err

    def _open(self) -> None:
        """AnyReader._open with the storage reconciled and a tolerant hash check."""
        if not self.is2:
            super()._open()
            return
        assert self.stack
        for reader in self.readers:
            self.stack.enter_context(reader)
        self.unreadable, self.open_notes = {}, []
        for reader in self.readers:
            self._reconcile(reader)
        connections = [y for x in self.readers for y in x.connections]
        typs: dict[str, Any] = {}
        claims: dict[tuple[str, str], list[str]] = {}   # (type, stored hash) -> topics
        definitions = [x for x in connections
                       if x.msgdef.format != MessageDefinitionFormat.NONE]
        if definitions:
            for conn in definitions:
                if conn.msgdef.format == MessageDefinitionFormat.MSG:
                    typs.update(get_types_from_msg(conn.msgdef.data, conn.msgtype))
                else:
                    sep = '=' * 80 + '\n'
                    if conn.msgdef.data.startswith(f'{sep}IDL: '):
                        for msgdef in conn.msgdef.data.split(sep)[1:]:
                            _, idl = msgdef.split('\n', 1)
                            typs.update(get_types_from_idl(idl))
                    else:
                        typs.update(get_types_from_idl(conn.msgdef.data))
                if conn.digest:
                    claims.setdefault((conn.msgtype, conn.digest), []).append(conn.topic)
        elif self.default_typestore:
            typs.update(self.default_typestore.fielddefs)
        else:
            raise AnyReaderError('Bag contains no type definitions. Instantiate AnyReader '
                                 'with a default_typestore argument.')
        store = get_typestore(Stores.EMPTY)
        store.register(typs)
        self._check_hashes(store, typs, claims)
        self.connections = connections
        self.typestore = store

    def _reconcile(self, reader: Any) -> None:
        """Pair every storage connection of a rosbag2 directory with a metadata.yaml topic."""
        directory = getattr(reader, 'storage', None)
        storages = getattr(directory, 'storages', None)
        if storages is None:   # a storage file read directly: its own connections
            return
        meta: list[Any] = directory.connections
        differ: dict[str, list[str]] = {}    # what differs -> topics
        stored: dict[str, int] = {}          # topic -> messages in the storage (paired)
        conflicts: dict[str, str] = {}
        for storage in storages:
            for i, conn in enumerate(storage.connections):
                if any(_strict_match(y, conn) for y in meta):
                    stored[conn.topic] = stored.get(conn.topic, 0) + int(conn.msgcount or 0)
                    continue
                same = [j for j, y in enumerate(meta)
                        if y.topic == conn.topic and y.msgtype == conn.msgtype]
                if not same:
                    types = sorted({y.msgtype for y in meta if y.topic == conn.topic})
                    if types:
                        conflicts[conn.topic] = (f'type {", ".join(types)} in metadata.yaml, '
                                                 f'{conn.msgtype} in the storage')
                    continue
                j = same[0]
                m_ext, s_ext = meta[j].ext, conn.ext
                fmt_m = getattr(m_ext, 'serialization_format', None)
                fmt_s = getattr(s_ext, 'serialization_format', None)
                if fmt_m != fmt_s:
                    conflicts[conn.topic] = (f'serialization {fmt_m!r} in metadata.yaml, '
                                             f'{fmt_s!r} in the storage')
                    continue
                what = []
                q_m = list(getattr(m_ext, 'offered_qos_profiles', None) or [])
                q_s = list(getattr(s_ext, 'offered_qos_profiles', None) or [])
                if q_m != q_s:
                    what.append(_qos_difference(q_m, q_s))
                if conn.digest and meta[j].digest and conn.digest != meta[j].digest:
                    # the storage holds the data and its definition: its hash is the one
                    what.append(f'the type hash of {conn.msgtype}: {_short(meta[j].digest)} '
                                f'in metadata.yaml, {_short(conn.digest)} in the storage')
                    meta[j] = meta[j]._replace(digest=conn.digest)
                storage.connections[i] = conn._replace(ext=m_ext, digest=meta[j].digest)
                stored[conn.topic] = stored.get(conn.topic, 0) + int(conn.msgcount or 0)
                for item in what or ['how the topic is described']:
                    topics = differ.setdefault(item, [])
                    if conn.topic not in topics:
                        topics.append(conn.topic)
        counts: dict[str, int] = {}
        for y in meta:
            counts[y.topic] = counts.get(y.topic, 0) + int(y.msgcount or 0)
        for topic, n in counts.items():
            if n and topic not in stored:
                why = conflicts.get(topic, 'no storage file has the topic')
                self.unreadable[topic] = (
                    f'metadata.yaml counts {n} {topic} message(s) but the storage gives none '
                    f'({why}): metadata.yaml and the storage disagree; {_REINDEX}')
        if differ:
            parts = [', '.join(topics) + f' ({what})' for what, topics in differ.items()]
            listed = {t for topics in differ.values() for t in topics}
            counted = ''.join(f'; metadata.yaml counts {counts.get(t, 0)} {t} messages, the '
                              f'storage holds {stored.get(t, 0)}' for t in sorted(listed)
                              if counts.get(t, 0) != stored.get(t, 0))
            self.open_notes.append(
                'metadata.yaml and the storage disagree on ' + '; '.join(parts) +
                ': rosbags alone yields no message of ' +
                ('this topic' if len(listed) == 1 else 'these topics') +
                f'; read from the storage anyway{counted}; {_REINDEX}')

    def _check_hashes(self, store: Typestore, typs: dict[str, Any],
                      claims: dict[tuple[str, str], list[str]]) -> None:
        """rosbags' check that a stored type hash is its definition's, except for a definition
        with the same fields as this project's typestore's (read as such, one note)."""
        ours = typestore()
        accepted: list[str] = []
        for (msgtype, digest), topics in claims.items():
            have = store.hash_rihs01(msgtype)
            if have == digest:
                continue
            where = ', '.join(sorted(set(topics)))
            differs = _field_difference(typs, ours, msgtype)
            if differs:
                raise BagReadError(
                    f'topic {where}: the stored type hash of {msgtype} ({digest}) is not the '
                    f'hash of the bag\'s definition of it ({have}), and {differs}: the '
                    'messages cannot be read safely. If only metadata.yaml is wrong, '
                    f'{_REINDEX}; otherwise rewrite the bag with the right type hash or '
                    're-record it')
            # same names and types of fields, so the same CDR layout: the typestore built
            # from the bag's definitions reads it as ours does
            accepted.append(f'{msgtype} on {where} ({_short(digest)} instead of '
                            f'{_short(have)})')
        if accepted:
            self.open_notes.append(
                'stored type hash not the hash of its definition: ' + '; '.join(accepted) +
                f': read with the ROS 2 Jazzy (or {_PKG}) definition, which has the same '
                'fields')

    def apply_remap(self, remap: dict[str, str], namespace: str = '') -> None:
        """Rename connections: explicit ``remap`` first, then strip ``namespace``.

        A recorded topic ``<namespace>/x`` is read as ``/x`` unless the bag also has ``/x``.
        Two recorded topics mapped onto one name raise :class:`BagReadError` (ambiguous).
        """
        ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
        present = {c.topic for c in self.connections}
        alias: dict[str, str] = {}
        for topic in sorted(present):
            if topic in remap:
                alias[topic] = remap[topic]
            elif ns and topic.startswith(ns + '/') and topic[len(ns):] not in present:
                alias[topic] = topic[len(ns):]
        targets: dict[str, str] = {}
        for topic in sorted(present):
            new = alias.get(topic, topic)
            if new in targets and targets[new] != topic:
                raise BagReadError(f'topic remapping is ambiguous: {targets[new]} and {topic} '
                                   f'would both be read as {new}')
            targets[new] = topic
        self.topic_alias = {k: v for k, v in alias.items() if k != v}
        if self.topic_alias:
            self._originals = {(id(c.owner), c.id): c for c in self.connections}
            self.connections[:] = [c._replace(topic=self.topic_alias.get(c.topic, c.topic))
                                   for c in self.connections]

    def messages(self, connections: Any = (), start: int | None = None,
                 stop: int | None = None) -> Iterator[tuple[Any, int, bytes]]:
        """AnyReader.messages on renamed connections: the storage is asked with the recorded
        connections and the yielded ones carry the analysed topic names."""
        originals = getattr(self, '_originals', None)
        if not originals:
            yield from super().messages(connections, start, stop)
            return
        asked = [originals.get((id(c.owner), c.id), c) for c in connections]
        alias = self.topic_alias
        for conn, t_ns, data in super().messages(asked, start, stop):
            yield (conn._replace(topic=alias[conn.topic]) if conn.topic in alias else conn,
                   t_ns, data)

    def __enter__(self) -> OpenedReader:
        if not self.stack:
            self.open()
        return self


def _short(digest: str) -> str:
    """A type hash shortened for a note (``RIHS01_`` and 12 hex digits)."""
    return digest[:19] + '...' if len(digest) > 22 else digest


@dataclass(frozen=True)
class BagMessage:
    """One message of a bag: topic, type, bag time [ns] and raw CDR bytes."""

    topic: str
    msgtype: str
    stamp_ns: int
    data: bytes


#: an mcap file's first and last eight bytes
MCAP_MAGIC = b'\x89MCAP0\r\n'
#: mcap records ending the data section: DataEnd, Footer
_MCAP_DATA_END, _MCAP_FOOTER = 0x0F, 0x02


def mcap_is_complete(path: str | os.PathLike[str]) -> bool:
    """Whether an mcap file ends with the mcap magic (a recorder killed, a disk full or a copy
    interrupted leaves the file without its footer and summary)."""
    p = Path(path)
    size = p.stat().st_size
    if size < 16:
        return False
    with p.open('rb') as f:
        f.seek(size - 8)
        return f.read(8) == MCAP_MAGIC


def salvage_mcap(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> tuple[int, int]:
    """Copy the complete records of a cut-short mcap file ``src`` into ``dst`` and close it
    with a summary of its own: the schemas and channels, a chunk index and message indexes
    written from the chunks' contents, statistics, a Footer and the end magic. Returns
    (bytes of ``src`` kept, bytes in ``src``).

    A record is kept when all of its bytes are there (a chunk also when it decodes); the first
    one cut short and everything after it are lost (with the recorder's chunks, up to one
    chunk: 0.75-1 MiB). The index lets readers order the messages by log time: rosbags
    refuses a summary-less file whose log times are out of order, as a recorder with several
    threads writes them. Raises :class:`BagReadError` when ``src`` does not start like an mcap
    file.
    """
    import struct

    from rosbags.rosbag2.storage_mcap import decompress

    def record(op: int, body: bytes) -> bytes:
        return bytes([op]) + struct.pack('<Q', len(body)) + body

    src, dst = Path(src), Path(dst)
    size = src.stat().st_size
    schemas: dict[int, bytes] = {}
    channels: dict[int, bytes] = {}
    counts: dict[int, int] = {}
    chunk_index: list[bytes] = []
    t_lo, t_hi = 2**63 - 1, 0

    def keep_definition(op: int, body: bytes) -> None:
        if op in (0x03, 0x04):
            (schemas if op == 0x03 else channels)[struct.unpack_from('<H', body)[0]] = body

    def chunk_messages(data: bytes) -> dict[int, list[tuple[int, int]]]:
        """A chunk's schemas and channels (kept) and its messages per channel: (log time,
        offset in the chunk's records)."""
        msgs: dict[int, list[tuple[int, int]]] = {}
        at = 0
        while at + 9 <= len(data):
            op, n = data[at], struct.unpack_from('<Q', data, at + 1)[0]
            body = data[at + 9:at + 9 + n]
            keep_definition(op, body)
            if op == 0x05:
                cid, _, log_time = struct.unpack_from('<HIQ', body)
                msgs.setdefault(cid, []).append((log_time, at))
            at += 9 + n
        return msgs

    with src.open('rb') as f, dst.open('wb') as out:
        head = f.read(8)
        if head != MCAP_MAGIC:
            raise BagReadError(f'{src}: not an mcap file (no mcap magic at its start)')
        out.write(head)
        pos = 8
        while pos + 9 <= size:
            header = f.read(9)
            op, length = header[0], int.from_bytes(header[1:], 'little')
            if op in (_MCAP_DATA_END, _MCAP_FOOTER) or pos + 9 + length > size:
                break
            body = f.read(length)
            if op == 0x07:          # message indexes: written anew after each chunk
                pos += 9 + length
                continue
            if op != 0x06:          # header, schemas, channels, metadata ...: as they are
                keep_definition(op, body)
                out.write(header + body)
                pos += 9 + length
                continue
            start, end, raw_size, crc = struct.unpack_from('<QQQI', body)
            n_comp = struct.unpack_from('<I', body, 28)[0]
            comp = body[32:32 + n_comp]
            n = struct.unpack_from('<Q', body, 32 + n_comp)[0]
            data = body[40 + n_comp:40 + n_comp + n]
            try:
                msgs = chunk_messages(decompress(data, comp.decode(), raw_size, crc))
            except Exception:       # a chunk that does not decode: the file ends before it
                break
            pos += 9 + length
            chunk_at = out.tell()
            out.write(header + body)
            index_at = out.tell()
            offsets = b''
            for cid, entries in sorted(msgs.items()):
                offsets += struct.pack('<HQ', cid, out.tell())
                rows = b''.join(struct.pack('<QQ', t, o) for t, o in sorted(entries))
                out.write(record(0x07, struct.pack('<HI', cid, len(rows)) + rows))
                counts[cid] = counts.get(cid, 0) + len(entries)
            if msgs:
                t_lo, t_hi = min(t_lo, start), max(t_hi, end)
            chunk_index.append(record(0x08, struct.pack('<QQQQ', start, end, chunk_at,
                                                        index_at - chunk_at)
                                      + struct.pack('<I', len(offsets)) + offsets
                                      + struct.pack('<Q', out.tell() - index_at)
                                      + struct.pack('<I', n_comp) + comp
                                      + struct.pack('<QQ', n, raw_size)))
        out.write(record(_MCAP_DATA_END, bytes(4)))
        summary_at = out.tell()
        for cid in sorted(schemas):
            out.write(record(0x03, schemas[cid]))
        for cid in sorted(channels):
            out.write(record(0x04, channels[cid]))
        for rec in chunk_index:
            out.write(rec)
        stats = b''.join(struct.pack('<HQ', cid, c) for cid, c in sorted(counts.items()))
        out.write(record(0x0B, struct.pack('<QHIIIIQQ', sum(counts.values()), len(schemas),
                                           len(channels), 0, 0, len(chunk_index),
                                           t_lo if counts else 0, t_hi)
                         + struct.pack('<I', len(stats)) + stats))
        out.write(record(_MCAP_FOOTER, struct.pack('<QQI', summary_at, 0, 0)))
        out.write(MCAP_MAGIC)
    return pos, size


def _salvaged(p: Path, notes: list[str], tmp: list[Any]) -> list[Path] | None:
    """The mcap files of bag ``p`` (a directory or one file) with the cut-short ones
    replaced by salvaged copies in a temporary directory (appended to ``tmp``); None when
    every file is complete (or ``p`` holds no mcap file)."""
    import tempfile

    files = sorted(p.glob('*.mcap')) if p.is_dir() else [p] if p.suffix == '.mcap' else []
    cut = [f for f in files if not mcap_is_complete(f)]
    if not cut:
        return None
    where = Path(tempfile.mkdtemp(prefix='hexapod_salvage_'))
    tmp.append(where)
    out = []
    empty = 0
    for f in files:
        if f not in cut:
            out.append(f)
            continue
        dst = where / f.name
        kept, size = salvage_mcap(f, dst)
        if kept <= 1024:
            empty += 1
            if empty == len(files):
                shutil.rmtree(where, ignore_errors=True)
                raise BagReadError(
                    f'cannot read bag {p}: cut short (no mcap footer: the recording was '
                    'killed, the disk filled or the copy was interrupted) before any complete '
                    'record (recorders write chunks of about 1 MiB): nothing to read')
        out.append(dst)
        read = (f'its complete records read ({kept / 2**20:.2f} of {size / 2**20:.2f} MiB), '
                'the rest lost') if kept > 1024 else \
            f'none of its records is complete ({size / 2**20:.2f} MiB lost)'
        notes.append(
            f'{f}: cut short (no mcap footer: the recording was killed, the disk filled or the '
            f'copy was interrupted); {read}'
            + ('; metadata.yaml ignored (its counts include what is lost)'
               if p.is_dir() and (p / 'metadata.yaml').is_file() else ''))
    return out


def open_reader(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], *,
                remap: dict[str, str] | None = None, namespace: str | None = None
                ) -> OpenedReader:
    """Open one bag (or several rosbag1 files) for reading, already opened.

    Bags without message definitions (e.g. Foxy-era sqlite3) fall back to the Jazzy typestore
    plus ``hexapod_interfaces``. Raises :class:`BagNotFoundError` or :class:`BagReadError` with
    a one-line message naming the path and the problem.

    ``remap`` (recorded topic -> analysed topic) and ``namespace`` (a prefix stripped from
    recorded topics) rename the reader's connections; when both are None the process-wide
    remapping of the ``HEXAPOD_BAG_REMAP`` environment variable applies (see module doc).
    """
    items = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    resolved: list[Path] = []
    notes: list[str] = []
    salvage_dirs: list[Path] = []
    for p in (Path(x) for x in items):
        if not p.exists():
            raise BagNotFoundError(f'no such bag: {p}')
        salvaged = _salvaged(p, notes, salvage_dirs)
        if salvaged is not None:
            # a cut-short mcap file: its complete records, beside the bag's other files
            resolved.extend(salvaged)
            continue
        if p.is_dir() and not (p / 'metadata.yaml').is_file():
            mcaps = sorted(p.glob('*.mcap'))
            if mcaps:
                # mcap files carry their own schemas and channels: read them without the
                # rosbag2 metadata (lost in a copy, or a recording killed before it was written)
                resolved.extend(mcaps)
                notes.append(f'{p}: no metadata.yaml; read its {len(mcaps)} mcap file(s) '
                             'directly')
                continue
            storage = sorted(x.name for x in p.glob('*.db3'))
            hint = f' (sqlite3 files {storage} but no metadata.yaml: recreate it with ' \
                   '`ros2 bag reindex`)' if storage else ''
            raise BagReadError(f'not a rosbag2 bag (no metadata.yaml): {p}{hint}')
        resolved.append(p)
    try:
        reader = OpenedReader(resolved, default_typestore=typestore())
        reader.salvage_dirs = salvage_dirs
        reader.open()
    except Exception as err:  # rosbags raises several unrelated types for bad files
        for d in salvage_dirs:
            shutil.rmtree(d, ignore_errors=True)
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        where = ', '.join(str(p) for p in resolved)
        raise BagReadError(f'cannot read bag {where}: {msg}') from err
    reader.topic_alias = {}
    reader.notes = notes + list(getattr(reader, 'open_notes', ()))
    if remap is None and namespace is None:
        remap, namespace = _remap_from_env()
    if remap or namespace:
        try:
            reader.apply_remap(dict(remap or {}), namespace or '')
        except BagReadError:
            reader.close()
            raise
    return reader


#: the label of :func:`message_progress`'s bars while one is active
_MESSAGE_BAR: ContextVar[str | Callable[[int], Any] | None] = ContextVar(
    'hexapod_message_bar', default=None)


@contextmanager
def message_progress(desc: str, *, disable: bool = False,
                     callback: Callable[[int], Any] | None = None) -> Iterator[None]:
    """While active, every :func:`iter_messages` of this thread shows a progress bar of the
    messages read (stderr, below the command's own bar, total from the bag's message counts):
    a single large bag then shows its progress, not ``0/1`` for minutes.

    ``disable`` (a command's ``--no-progress``) and a stderr that is not a terminal show none.
    ``callback`` instead receives the number of messages read every 4096 and at the end (a
    worker process reporting to its parent's bar, ``slip --jobs``).
    """
    on = not disable and hasattr(sys.stderr, 'isatty') and sys.stderr.isatty()
    token = _MESSAGE_BAR.set(callback if callback is not None else desc if on else None)
    try:
        yield
    finally:
        _MESSAGE_BAR.reset(token)


def iter_messages(reader: AnyReader, topics: Sequence[str] | None = None,
                  start_ns: int | None = None, stop_ns: int | None = None, *,
                  dedupe: bool = True, duplicates: dict[str, int] | None = None,
                  progress: Callable[[int], Any] | None = None
                  ) -> Iterator[BagMessage]:
    """Raw messages in time order, optionally filtered by topic and bag-time window.

    Parameters
    ----------
    reader
        An open reader (:func:`open_reader`).
    topics
        Topics to read (all when None).
    start_ns, stop_ns
        Bag-time window [ns].
    dedupe
        Drop exact duplicates: a message of the same topic, log time and bytes as one already
        yielded (a recorder or relay that wrote some messages twice); a message recorded twice
        counts once. False yields every stored message (replaying a bag as recorded).
    duplicates
        Filled with topic -> number of duplicates dropped (for the readers' notes; see
        :func:`duplicates_note`).
    progress
        Called with the number of messages read since its last call (every 4096 messages and
        at the end), e.g. a tqdm's ``update``.
    """
    conns = [c for c in reader.connections if topics is None or c.topic in topics]
    unreadable = getattr(reader, 'unreadable', None)
    if unreadable:
        alias = getattr(reader, 'topic_alias', {})
        for recorded, why in sorted(unreadable.items()):
            if topics is None or alias.get(recorded, recorded) in topics:
                where = ', '.join(str(p) for p in getattr(reader, 'paths', ()))
                raise BagReadError(f'bag {where}: {why}')
    if not conns and topics is not None:
        return   # (rosbags reads every topic when given no connection)
    bar_desc = _MESSAGE_BAR.get() if progress is None else None
    if callable(bar_desc):
        yield from iter_messages(reader, topics, start_ns, stop_ns, dedupe=dedupe,
                                 duplicates=duplicates, progress=bar_desc)
        return
    if bar_desc is not None:
        from tqdm import tqdm

        total = sum(int(getattr(c, 'msgcount', 0) or 0) for c in conns)
        bar = tqdm(total=total or None, desc=bar_desc, unit='msg', unit_scale=True,
                   leave=False, file=sys.stderr, mininterval=0.5)
        try:
            yield from iter_messages(reader, topics, start_ns, stop_ns, dedupe=dedupe,
                                     duplicates=duplicates, progress=bar.update)
        finally:
            bar.close()
        return
    body = _mocap_tf_from_env()
    tf_mocap = body is not None and any(c.topic == '/mocap/body' and c.msgtype == TF_TYPE
                                        for c in conns)
    found = 0
    pairs: dict[tuple[str, str], int] = {}
    # exact duplicates share the log time: the messages stored at the current log time
    group_t: int | None = None
    group: set[tuple[str, bytes]] = set()
    read = 0
    # a topic the bag counts that gives no message at all (metadata.yaml and storage that
    # disagree in a way the reader did not foresee): checked when the whole bag is read
    whole = (start_ns is None or start_ns <= reader.start_time) and \
        (stop_ns is None or stop_ns >= reader.end_time)
    counted = {c.topic for c in conns if int(getattr(c, 'msgcount', 0) or 0) > 0} \
        if whole else set()
    # messages given per topic against the bag's counts: storage that ends early inside
    # (damaged bytes in an mcap chunk) gave 810 of 1000 messages of every topic in silence
    expected: dict[str, int] = {}
    if whole:
        for c in conns:
            expected[c.topic] = expected.get(c.topic, 0) + int(getattr(c, 'msgcount', 0) or 0)
    given: dict[str, int] = dict.fromkeys(expected, 0)
    try:
        for conn, stamp, data in reader.messages(connections=conns, start=start_ns,
                                                 stop=stop_ns):
            if counted:
                counted.discard(conn.topic)
            if whole:
                given[conn.topic] += 1
            if progress is not None:
                read += 1
                if read == 4096:
                    progress(read)
                    read = 0
            if dedupe:
                data = bytes(data)
                key = (conn.topic, data)
                if stamp != group_t:
                    group_t, group = stamp, {key}
                elif key in group:
                    if duplicates is not None:
                        duplicates[conn.topic] = duplicates.get(conn.topic, 0) + 1
                    continue
                else:
                    group.add(key)
            if tf_mocap and conn.topic == '/mocap/body' and conn.msgtype == TF_TYPE:
                # the body's pose among the transforms of /tf (--mocap-tf PARENT:CHILD)
                assert body is not None
                tf_msg = reader.deserialize(bytes(data), TF_TYPE)
                tr = pick_transform(tf_msg, *body)
                if tr is None:
                    if not found:
                        for t in tf_msg.transforms:
                            key = (str(t.header.frame_id), str(t.child_frame_id))
                            pairs[key] = pairs.get(key, 0) + 1
                    continue
                found += 1
                yield BagMessage('/mocap/body', TRANSFORM_TYPE, stamp,
                                 bytes(_serialize_like(reader, tr, TRANSFORM_TYPE)))
                continue
            yield BagMessage(conn.topic, conn.msgtype, stamp, bytes(data))
    except BagReadError:
        raise
    except Exception as err:
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise BagReadError(f'bag is truncated or corrupt: {msg}') from err
    if progress is not None and read:
        progress(read)
    if counted:
        where = ', '.join(str(p) for p in getattr(reader, 'paths', ()))
        n = {t: sum(int(c.msgcount or 0) for c in conns if c.topic == t) for t in counted}
        raise BagReadError(
            f'bag {where}: the bag counts ' + ', '.join(
                f'{n[t]} {t}' for t in sorted(counted)) + ' message(s) but the storage gave '
            f'none: metadata.yaml and the storage disagree; {_REINDEX}')
    short = {t: (given[t], n) for t, n in expected.items() if given[t] < n}
    if short:
        where = ', '.join(str(p) for p in getattr(reader, 'paths', ()))
        raise BagReadError(
            f'bag {where}: the storage gave ' + ', '.join(
                f'{g} of the {n} {t}' for t, (g, n) in sorted(short.items()))
            + ' message(s) the bag counts: the storage is damaged (or metadata.yaml is '
            f'not its own); {_REINDEX}')
    if tf_mocap and not found and start_ns is None and stop_ns is None:
        assert body is not None
        have = ', '.join(f'{a or "?"} -> {b or "?"} ({n})'
                         for (a, b), n in sorted(pairs.items(), key=lambda kv: -kv[1])[:8])
        raise BagReadError(f'/tf has no transform {body[0]} -> {body[1]} (--mocap-tf); it has '
                           f'{have or "no transforms"}')


def duplicates_note(duplicates: dict[str, int]) -> list[str]:
    """The note of :func:`iter_messages`' ``duplicates`` count (empty when none was dropped)."""
    total = sum(duplicates.values())
    if not total:
        return []
    per = ', '.join(f'{t} {n}' for t, n in sorted(duplicates.items()) if n)
    return [f'{total} duplicated message(s) ignored (recorded twice: same topic, log time '
            f'and bytes; {per})']


#: ``/tf`` messages and the transform they hold (--mocap-tf)
TF_TYPE = 'tf2_msgs/msg/TFMessage'
TRANSFORM_TYPE = 'geometry_msgs/msg/TransformStamped'


def _mocap_tf_from_env() -> tuple[str, str] | None:
    raw = os.environ.get(MOCAP_TF_ENV, '').strip()
    if not raw:
        return None
    try:
        return parse_mocap_tf(raw)
    except ValueError as err:
        raise BagReadError(f'{MOCAP_TF_ENV}: {err}') from err


def _serialize_like(reader: Any, msg: Any, msgtype: str) -> Any:
    """``msg`` serialised as the reader's own messages are (CDR for rosbag2, ROS 1 for rosbag1
    files), so that ``reader.deserialize`` reads it back."""
    store = reader.typestore
    if getattr(reader, 'is2', True):
        return store.serialize_cdr(msg, msgtype)
    return store.serialize_ros1(msg, msgtype)


class SampleColumns:
    """Samples of one frozen dataclass (the converters' ``*Sample``) stored as compact
    columns, rebuilt lazily: the readers of long bags hold every converted sample until the
    whole bag is read (stamp order, clock shifts), and as dataclasses whose numpy arrays are
    views of their message's CDR buffer that cost about 1.5 kB per message (a 60 min robot
    bag: 2 GB).

    Each field is a column: Python floats and ints in ``array.array`` (8 bytes a value),
    strings and name tuples as indices into a table of the distinct values, 1-D numpy arrays
    concatenated into one buffer with a length per row; a field whose type changes from one
    sample to the next (none of the converters' does) falls back to a list. ``len``, ``[k]``
    and iteration rebuild samples equal to the appended ones (numbers as Python floats and
    ints, arrays as read-only views of the column); the first read seals the columns
    (appending after it raises ``RuntimeError``).
    """

    def __init__(self) -> None:
        self._cls: Any = None
        self._fields: tuple[str, ...] = ()
        self._kinds: list[str] = []      # per field: f, i (array.array), o (interned), a, l
        self._cols: list[Any] = []
        self._ndarray: Any = None
        self._tables: list[tuple[dict[Any, int], list[Any]]] = []
        self._lens: list[Any] = []       # 'a' fields: array('q') of row lengths
        self._dtypes: list[Any] = []
        self._n = 0
        self._views: list[Any] | None = None   # 'a' fields after sealing: (buffer, offsets)
        self._getters: list[Callable[[int], Any]] = []

    # -- writing -----------------------------------------------------------------------------
    def append(self, sample: Any) -> None:
        """Add one sample (a dataclass instance of the first sample's class)."""
        if self._views is not None:
            raise RuntimeError('SampleColumns already read: no more samples can be added')
        if self._cls is None:
            self._setup(sample)
        elif type(sample) is not self._cls:
            raise TypeError(f'SampleColumns of {self._cls.__name__} given a '
                            f'{type(sample).__name__}')
        kinds, cols = self._kinds, self._cols
        for j, name in enumerate(self._fields):
            value = getattr(sample, name)
            if kinds[j] == 'f' and type(value) is float:   # most fields: inline
                cols[j].append(value)
            elif not self._put(j, value):
                self._to_list(j)
                self._cols[j].append(value)
        self._n += 1

    def _setup(self, sample: Any) -> None:
        import array

        import numpy as np

        self._cls = type(sample)
        self._ndarray = np.ndarray
        self._fields = tuple(f.name for f in dataclass_fields(sample))
        for name in self._fields:
            value = getattr(sample, name)
            if type(value) is float:
                kind, col = 'f', array.array('d')
            elif type(value) is int and -2**63 <= value < 2**63:
                kind, col = 'i', array.array('q')
            elif isinstance(value, np.ndarray) and value.ndim == 1 and \
                    value.dtype.kind in 'biuf':
                kind, col = 'a', bytearray()
            elif _hashable(value):
                kind, col = 'o', array.array('q')
            else:
                kind, col = 'l', []
            self._kinds.append(kind)
            self._cols.append(col)
            self._tables.append(({}, []))
            self._lens.append(array.array('q') if kind == 'a' else None)
            self._dtypes.append(value.dtype if kind == 'a' else None)

    def _put(self, j: int, value: Any) -> bool:
        kind = self._kinds[j]
        if kind == 'f':
            if type(value) is not float:
                return False
            self._cols[j].append(value)
        elif kind == 'a':
            if type(value) is not self._ndarray or value.ndim != 1 or \
                    value.dtype != self._dtypes[j]:
                return False
            self._cols[j] += value.tobytes()
            self._lens[j].append(value.size)
        elif kind == 'i':
            if type(value) is not int or not -2**63 <= value < 2**63:
                return False
            self._cols[j].append(value)
        elif kind == 'o':
            if not _hashable(value):
                return False
            index, values = self._tables[j]
            key = (type(value), value)
            k = index.get(key)
            if k is None:
                k = index[key] = len(values)
                values.append(value)
            self._cols[j].append(k)
        else:
            self._cols[j].append(value)
        return True

    def _to_list(self, j: int) -> None:
        """Field ``j`` as a plain list of its values (a sample whose type differs)."""
        if self._kinds[j] == 'a':
            import numpy as np

            raw = bytes(self._cols[j])
            values, start = [], 0
            for length in self._lens[j]:
                values.append(np.frombuffer(raw, dtype=self._dtypes[j], count=length,
                                            offset=start * self._dtypes[j].itemsize))
                start += length
            self._cols[j] = values
        else:
            self._cols[j] = [self._value(j, k) for k in range(self._n)]
        self._kinds[j] = 'l'

    # -- reading -----------------------------------------------------------------------------
    def _seal(self) -> list[Any]:
        import array

        import numpy as np

        if self._views is None:
            views: list[Any] = []
            for j, kind in enumerate(self._kinds):
                if kind != 'a':
                    views.append(None)
                    continue
                buf = np.frombuffer(self._cols[j], dtype=self._dtypes[j]) \
                    if self._cols[j] else np.zeros(0, dtype=self._dtypes[j])
                buf.flags.writeable = False
                lens = np.frombuffer(self._lens[j], dtype=np.int64) if self._lens[j] else \
                    np.zeros(0, dtype=np.int64)
                offsets = np.zeros(lens.size + 1, dtype=np.int64)
                np.cumsum(lens, out=offsets[1:])
                # array.array: 8 bytes an offset, indexed as Python ints
                views.append((buf, array.array('q', offsets.tobytes())))
            self._views = views
            self._getters = [self._getter(j) for j in range(len(self._fields))]
        return self._views

    def _getter(self, j: int) -> Callable[[int], Any]:
        """Field ``j`` of row ``k`` (after sealing)."""
        kind, col = self._kinds[j], self._cols[j]
        if kind in ('f', 'i', 'l'):
            return col.__getitem__
        if kind == 'o':
            table = self._tables[j][1]
            return lambda k: table[col[k]]
        buf, offsets = self._views[j]   # type: ignore[index]
        return lambda k: buf[offsets[k]:offsets[k + 1]]

    def _value(self, j: int, k: int) -> Any:
        kind = self._kinds[j]
        if kind in ('f', 'i', 'l'):
            return self._cols[j][k]
        if kind == 'o':
            return self._tables[j][1][self._cols[j][k]]
        buf, offsets = self._seal()[j]
        return buf[offsets[k]:offsets[k + 1]]

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, k: int) -> Any:
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(self._n))]
        if k < 0:
            k += self._n
        if not 0 <= k < self._n:
            raise IndexError('SampleColumns index out of range')
        self._seal()
        return self._cls(*[get(k) for get in self._getters])

    def __iter__(self) -> Iterator[Any]:
        self._seal()
        cls, getters = self._cls, self._getters
        for k in range(self._n):
            yield cls(*[get(k) for get in getters])

    # -- columns -----------------------------------------------------------------------------
    def column(self, name: str) -> Any:
        """A number field as a numpy array (float64 or int64; a view of the column: shifting
        it in place shifts the samples), any other field as a list of its values."""
        import numpy as np

        j = self._fields.index(name) if self._fields else -1
        if j < 0:
            return np.zeros(0)
        kind = self._kinds[j]
        if kind in ('f', 'i'):
            if not self._n:
                return np.zeros(0, dtype=float if kind == 'f' else np.int64)
            return np.frombuffer(self._cols[j], dtype=float if kind == 'f' else np.int64)
        return [self._value(j, k) for k in range(self._n)]

    def distinct(self, name: str) -> list[Any]:
        """The distinct values of a string or tuple field, in order of first appearance."""
        if not self._n:
            return []
        j = self._fields.index(name)
        if self._kinds[j] == 'o':
            return list(self._tables[j][1])
        seen: list[Any] = []
        for k in range(self._n):
            v = self._value(j, k)
            if v not in seen:
                seen.append(v)
        return seen

    def stacked(self, name: str) -> Any:
        """An array field as one 2-D array (n, length) when every row has the same length,
        else (and without samples) None."""
        import numpy as np

        if not self._n:
            return None
        j = self._fields.index(name)
        if self._kinds[j] != 'a':
            return None
        buf, offsets = self._seal()[j]
        width = offsets[1] - offsets[0]
        if offsets[-1] != width * self._n:
            return None
        lens = np.diff(np.asarray(offsets))
        if np.any(lens != width):
            return None
        return buf.reshape(self._n, width)

    def shift(self, name: str, dt: float) -> None:
        """Add ``dt`` to a float field of every sample (a clock offset)."""
        j = self._fields.index(name) if self._fields else -1
        if j < 0 or not self._n:
            return
        if self._kinds[j] == 'f':
            import numpy as np

            view = np.frombuffer(self._cols[j], dtype=float)
            view += dt
            del view
        else:
            self._cols[j] = [v + dt for v in self.column(name)]
            self._kinds[j] = 'l'
            if self._views is not None:
                self._getters[j] = self._getter(j)


def _hashable(value: Any) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True


def prepare_battery_columns(samples: SampleColumns) -> tuple[SampleColumns, list[str]]:
    """:func:`hexapod_common.battery.prepare_battery_samples` on the ``BatterySample`` columns
    of a reader. One battery in V and A (the usual case) is checked on the columns and
    returned unchanged; otherwise (milli-units, several batteries, ``--battery-source``,
    ``present`` false somewhere) the
    samples are rebuilt for it and its result stored as columns again. Raises ValueError as
    it does."""
    import numpy as np

    from hexapod_common.battery import (
        milli_factors,
        prepare_battery_samples,
        selected_source,
        unmeasured_power,
    )

    if not len(samples):
        return samples, []
    if len(samples.distinct('source')) == 1 and selected_source() is None and \
            False not in samples.distinct('present'):
        v, i = samples.column('voltage_v'), samples.column('current_a')
        if isinstance(v, np.ndarray) and isinstance(i, np.ndarray) and \
                milli_factors(float(np.median(np.abs(v))),
                              float(np.median(np.abs(i)))) == (1.0, 1.0):
            why = unmeasured_power(v, i)
            if why:
                raise ValueError(why)
            return samples, []
    out, notes = prepare_battery_samples(list(samples))
    cols = SampleColumns()
    for b in out:
        cols.append(b)
    return cols, notes
