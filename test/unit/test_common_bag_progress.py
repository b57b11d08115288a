"""Inside ``message_progress`` every ``iter_messages`` shows a bar of the messages read (a
single long bag shows progress); none with ``disable`` or a stderr that is not a terminal."""

from __future__ import annotations

import io

from hexapod_common.bags import iter_messages, message_progress, open_reader
from hexapod_common.testbags import write_mixed_bag


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def _read(bag, monkeypatch, stream: io.StringIO, **kw) -> int:
    monkeypatch.setattr('sys.stderr', stream)
    with open_reader(bag) as reader, message_progress('test: bag', **kw):
        return sum(1 for _ in iter_messages(reader))


def test_messages_read_show_on_a_terminal_only(tmp_path, monkeypatch):
    bag = tmp_path / 'b'
    total = sum(write_mixed_bag(bag, 9000).values())
    tty = _Tty()
    assert _read(bag, monkeypatch, tty) == total
    # a bar labelled with the total from the bag's message counts (cleared at the end)
    assert total == 9000 and 'test: bag:' in tty.getvalue() and '/9.00k' in tty.getvalue()
    assert 'msg' in tty.getvalue()
    quiet, pipe = _Tty(), io.StringIO()
    assert _read(bag, monkeypatch, quiet, disable=True) == total
    assert _read(bag, monkeypatch, pipe) == total
    assert quiet.getvalue() == '' and pipe.getvalue() == ''
