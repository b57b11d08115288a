"""The drivers apply one command source only (hexapod_common.publishers.FirstPublisherGate):
while two publishers interleave on ``/joint_commands`` (a second gait node before it finds the
first, a lab's teleop), the servos followed both and jumped between two targets. Now only the
publisher that was there first passes; when it stops, the remaining one is followed after
FOLLOWED_QUIET_S; a respawned publisher (numbers anew) keeps working; a middleware without
numbers passes everything, as before."""

from __future__ import annotations

import pytest

from hexapod_common.publishers import (
    FOLLOWED_QUIET_S,
    FirstPublisherGate,
)


def _stream(name, rate_hz, t0_s, t1_s, seq0=1, phase_s=0.0):
    """(send time, name, number) of a publisher sending at ``rate_hz`` from ``t0_s`` (its
    number ``seq0`` then) until ``t1_s``."""
    out, k = [], 0
    while True:
        t = t0_s + phase_s + k / rate_hz
        if t >= t1_s:
            return out
        out.append((round(t, 9), name, seq0 + k))
        k += 1


def _run(*streams, gate=None, latency_s=0.001):
    """Feed the merged streams in send order (each arrives ``latency_s`` later); returns the
    gate and, per publisher, the send times of its messages that passed and were dropped."""
    gate = gate or FirstPublisherGate()
    passed: dict[str, list[float]] = {}
    dropped: dict[str, list[float]] = {}
    for t, name, seq in sorted(x for s in streams for x in s):
        ok = gate.admit(seq, t, t + latency_s)
        (passed if ok else dropped).setdefault(name, []).append(t)
    return gate, passed, dropped


def test_two_interleaved_publishers_only_the_first_passes():
    a = _stream('a', 100.0, 0.0, 10.0)                       # walking since t = 0
    b = _stream('b', 100.0, 4.0, 5.0, phase_s=0.004)         # a second gait node, 1 s
    gate, passed, dropped = _run(a, b)
    assert len(passed['a']) == len(a) and 'a' not in dropped
    assert 'b' not in passed and len(dropped['b']) == len(b)
    assert gate.dropped == len(b) and gate.take_switches() == []


def test_interleaved_with_similar_counts_no_swap_at_the_switch():
    """Two publishers a few numbers apart (b started 3 messages after a, same rate): the
    highest-number-below rule can swap them where the counts meet; the gate must not."""
    a = _stream('a', 100.0, 0.0, 3.0)
    b = _stream('b', 100.0, 0.03, 3.0, phase_s=0.005)
    gate, passed, dropped = _run(a, b)
    assert len(passed['a']) == len(a) and 'b' not in passed


def test_the_first_stops_then_the_second_is_followed_after_the_quiet_time():
    a = _stream('a', 100.0, 0.0, 2.0)                        # killed at t = 2
    b = _stream('b', 100.0, 1.5, 5.0, phase_s=0.003)
    gate, passed, dropped = _run(a, b)
    assert len(passed['a']) == len(a)
    # b dropped while a lived and for the quiet time after a's last message, then followed
    assert max(dropped['b']) < 2.0 + FOLLOWED_QUIET_S + 0.011
    assert min(passed['b']) >= 2.0 + FOLLOWED_QUIET_S - 0.011
    assert len(passed['b']) + len(dropped['b']) == len(b)
    [switch] = gate.take_switches()
    assert switch.reason == 'quiet' and switch.silent_s >= FOLLOWED_QUIET_S


def test_a_respawned_publisher_passes_within_the_quiet_time():
    """One publisher, killed and respawned at once (its numbers restart at 1, the old series
    silent): dropped at most the quiet time; after a real respawn delay, nothing dropped."""
    old = _stream('a', 100.0, 0.0, 2.0)
    new = _stream('a2', 100.0, 2.0, 6.0)                     # at once, numbers from 1
    gate, passed, dropped = _run(old, new)
    assert min(passed['a2']) <= 2.0 + FOLLOWED_QUIET_S + 0.011
    assert max(dropped.get('a2', [0.0])) < 2.0 + FOLLOWED_QUIET_S
    assert len(passed['a2']) >= len(new) - FOLLOWED_QUIET_S * 100 - 1
    # a respawn that takes longer than the quiet time (the usual case): nothing dropped
    later = _stream('a2', 100.0, 2.8, 6.0)
    gate, passed, dropped = _run(old, later)
    assert dropped == {} and len(passed['a2']) == len(later)
    # the measured respawn: the dead writer's last number 255, the new one's first seen 7
    gate = FirstPublisherGate()
    assert all(gate.admit(n, n * 0.01, n * 0.01) for n in range(144, 256))
    assert all(gate.admit(n, 3.0 + n * 0.01, 3.0 + n * 0.01) for n in range(7, 1500))


def test_a_respawn_that_repeats_counts_the_old_one_reached():
    """The new series passes the old dead one's last number: still the new series."""
    old = _stream('a', 100.0, 0.0, 0.5)                      # numbers 1..50
    new = _stream('a2', 100.0, 1.2, 4.0)                     # 1..280: past 50
    gate, passed, dropped = _run(old, new)
    assert dropped == {} and len(passed['a2']) == len(new)


def test_unnumbered_messages_all_pass():
    gate = FirstPublisherGate()
    assert all(gate.admit(None, None, k * 0.01) for k in range(100))
    assert gate.unnumbered == 100 and gate.dropped == 0 and gate.followed is None


def test_three_publishers_the_first_then_the_next_heard():
    a = _stream('a', 100.0, 0.0, 3.0)
    b = _stream('b', 50.0, 1.0, 6.0, phase_s=0.003)
    c = _stream('c', 100.0, 2.0, 6.0, phase_s=0.007)
    gate, passed, dropped = _run(a, b, c)
    assert len(passed['a']) == len(a)
    # a stops at 3: b, heard before c, is followed after the quiet time; c never
    assert 'c' not in passed
    assert min(passed['b']) >= 3.0 + FOLLOWED_QUIET_S - 0.021
    assert all(t < 3.0 + FOLLOWED_QUIET_S + 0.021 for t in dropped['b'])


@pytest.mark.parametrize('phase_s', [0.0, 0.0013, 0.045, 0.05])
def test_a_10_hz_first_publisher_is_kept_beside_a_100_hz_newcomer(phase_s):
    """The newcomer's count overtakes the first's (after about 0.6 s). With the newcomer
    starting 4.94-4.96 s in (phases 0.045, 0.05), PublisherSequences' highest-number-below
    rule hands the rest of its numbers to the first's series at the crossing (checked while
    writing this); the gate's series keep their identity by their rates."""
    a = _stream('a', 10.0, 0.0, 20.0)                        # numbers 1..200
    b = _stream('b', 100.0, 4.9, 12.0, phase_s=phase_s)      # crosses a's count near 56
    gate, passed, dropped = _run(a, b)
    assert len(passed['a']) == len(a) and 'a' not in dropped
    assert 'b' not in passed and len(dropped['b']) == len(b)
    assert [s.last_seq for s in gate.live_series()] == [len(a), len(b)]


def test_both_there_before_the_receiver_heard_anything_the_earlier_start_wins():
    """The receiver starts while a (walking since 0) and b (a newcomer since 9.6 s) both
    publish, and hears b first: a, which started first, is followed once both starts are
    known (a few messages), then only a."""
    a = _stream('a', 100.0, 0.0, 12.0)
    b = _stream('b', 100.0, 9.6, 11.0, phase_s=0.002)
    heard = [x for x in sorted(a + b) if x[0] >= 10.0]
    first = next(i for i, x in enumerate(heard) if x[1] == 'b')
    heard = heard[first:]                                     # b's message heard first
    gate, passed, dropped = _run(heard)
    assert len(dropped['a']) <= 2                             # until a's start is known
    assert len(passed['b']) <= 2
    late = [t for t in passed['b'] if t > 10.05]
    assert late == []
    [switch] = gate.take_switches()
    assert switch.reason == 'started earlier'


def test_a_slow_first_publisher_is_not_gone_between_its_messages():
    """A 1 Hz teleop followed first: the 100 Hz newcomer is not taken for the remaining one
    between two of its messages (the quiet time is 5 of its periods when longer)."""
    a = _stream('a', 1.0, 0.0, 20.0)
    b = _stream('b', 100.0, 5.5, 8.0, phase_s=0.003)
    gate, passed, dropped = _run(a, b)
    assert len(passed['a']) == len(a) and 'b' not in passed


def test_without_send_times_the_receiver_clock_is_used():
    gate = FirstPublisherGate()
    out = []
    for k in range(200):
        out.append(('a', gate.admit(1000 + k, None, k * 0.01)))
        if 50 <= k < 150:
            out.append(('b', gate.admit(k - 49, None, k * 0.01 + 0.004)))
    assert all(ok for n, ok in out if n == 'a')
    assert not any(ok for n, ok in out if n == 'b')


def test_bad_settings_refused():
    with pytest.raises(ValueError):
        FirstPublisherGate(quiet_s=0.0)
    with pytest.raises(ValueError):
        FirstPublisherGate(window=1)


class _Logger:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def error(self, msg: str, **kw) -> None:
        self.lines.append(('error', msg))

    def warning(self, msg: str, **kw) -> None:
        self.lines.append(('warning', msg))

    def info(self, msg: str, **kw) -> None:
        self.lines.append(('info', msg))


class _Node:
    """What FirstPublisherWatch uses of a node: its logger and the graph's publishers."""

    def __init__(self) -> None:
        self.logger = _Logger()

    def get_logger(self) -> _Logger:
        return self.logger

    def get_publishers_info_by_topic(self, topic: str) -> list:
        return []


def _info(seq: int, t_s: float) -> dict:
    return {'publication_sequence_number': seq, 'source_timestamp': int(t_s * 1e9)}


def test_the_drivers_helper_drops_the_newcomer_and_says_so_once_then_sums_up():
    """The nodes' helper (node_utils.FirstPublisherWatch, used by dynamixel_driver,
    sim_robot and sim_bench): the error names the followed publisher (its frame_id), says
    the other's commands are ignored and how many; a summary when the episode ends."""
    from hexapod_common.node_utils import FirstPublisherWatch

    node = _Node()
    watch = FirstPublisherWatch(node)
    now = [0.0]
    watch.clock = lambda: now[0]
    applied = []
    for t, name, seq in sorted(_stream('a', 100.0, 0.0, 30.0)
                               + _stream('b', 100.0, 5.0, 6.0, phase_s=0.004)):
        now[0] = t + 0.001
        label = '/gait_a@1@1' if name == 'a' else '/gait_b@2@5'
        if watch.admit(_info(seq, t), label):
            applied.append(name)
    # the newcomer's first messages pass until its numbers have interleaved twice (one
    # publisher's never drop: review J5); then none
    assert applied.count('a') == 3000 and applied.count('b') <= 2
    assert 'b' not in applied[applied.index('b') + 3:] if 'b' in applied else True
    errors = [m for lvl, m in node.logger.lines if lvl == 'error']
    assert len(errors) == 1
    assert "frame_id '/gait_a@1@1'" in errors[0] and 'are ignored' in errors[0]
    assert 'dropped so far' in errors[0]
    summary = [m for lvl, m in node.logger.lines if lvl == 'warning']
    assert len(summary) == 1 and \
        f'{100 - applied.count("b")} commands of the other' in summary[0]
    # a middleware without numbers: everything applied, nothing said
    node = _Node()
    watch = FirstPublisherWatch(node)
    assert all(watch.admit({'publication_sequence_number': 0}) for _ in range(50))
    assert all(watch.admit(None) for _ in range(50))
    assert node.logger.lines == []


def test_the_drivers_helper_follows_a_respawn_and_says_it_at_info_level():
    from hexapod_common.node_utils import FirstPublisherWatch

    node = _Node()
    watch = FirstPublisherWatch(node)
    now = [0.0]
    watch.clock = lambda: now[0]
    ok = []
    for t, name, seq in _stream('a', 100.0, 0.0, 2.0) + _stream('a2', 100.0, 3.0, 4.0):
        now[0] = t
        ok.append(watch.admit(_info(seq, t)))
    assert all(ok) and watch.reported == 0
    assert [lvl for lvl, m in node.logger.lines] == ['info']
    assert 'silent for 1.0' in node.logger.lines[0][1]


def _watch():
    from hexapod_common.node_utils import FirstPublisherWatch

    node = _Node()
    watch = FirstPublisherWatch(node)
    now = [0.0]
    watch.clock = lambda: now[0]
    return node, watch, now


@pytest.mark.parametrize('case', ['clock_back', 'clock_forward_respawn', 'losses_after_rest',
                                  'losses_at_start'])
def test_one_publisher_is_never_dropped_whatever_its_clock_and_losses(case):
    """Review J5: the gate's series, matched by rate and send time, took one publisher for two:
    a send clock stepping back 1 s dropped 49 of its commands, an NTP step forward then a
    respawn 3,000, loss bursts after a rest 34, 15 lost after the first message 33. Nothing is
    dropped unless the numbers interleave (two live publishers)."""
    node, watch, now = _watch()
    msgs = []                              # (send time, number, arrival)
    if case == 'clock_back':
        msgs = [(k / 100, k + 1, k / 100) for k in range(300)]
        msgs += [(3.0 - 1.0 + k / 100, 301 + k, 3.0 + k / 100) for k in range(300)]
    elif case == 'clock_forward_respawn':
        msgs = [(k / 100, k + 1, k / 100) for k in range(100)]
        msgs += [(5000.0 + k / 100, 101 + k, 1.0 + k / 100) for k in range(100)]
        msgs += [(5003.0 + k / 100, 1 + k, 4.0 + k / 100) for k in range(3000)]  # respawn
    elif case == 'losses_after_rest':
        msgs = [(k / 1.0, k + 1, k / 1.0) for k in range(30)]          # 1 Hz, 30 s
        t0 = 90.0
        msgs += [(t0 + k / 100, 31 + k, t0 + k / 100) for k in range(300) if not 5 <= k < 20]
    else:
        msgs = [(k / 100, k + 1, k / 100) for k in range(300) if not 1 <= k < 16]
    for t, seq, arrival in msgs:
        now[0] = arrival
        assert watch.admit(_info(seq, t), '/gait_a@1@1'), (case, t, seq)
    assert watch.dropped == 0 and watch.reported == 0
    assert not [m for lvl, m in node.logger.lines if lvl in ('error', 'warning')]


def test_a_slow_publisher_heard_once_keeps_the_joints_from_a_newcomer():
    """Review J5: a 1 Hz teleop heard once (its rate unknown) was gone after 0.5 s: a 100 Hz
    gait node from 0.6 s took the joints (9 of the teleop's 10 commands dropped), or from
    0.2 s took them and gave them back. Now the teleop, there first, is followed once the
    numbers interleave; the gait node's commands are applied only before that."""
    node, watch, now = _watch()
    stream = sorted(_stream('t', 1.0, 0.0, 10.0) + _stream('g', 100.0, 0.6, 10.0))
    applied = {'t': 0, 'g': 0}
    for t, name, seq in stream:
        now[0] = t + 0.001
        if watch.admit(_info(seq, t)):
            applied[name] += 1
    assert applied['t'] == 10
    assert applied['g'] <= 41      # 0.6-1.0 s, before the teleop's second message
