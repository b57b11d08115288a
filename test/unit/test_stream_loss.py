"""Messages missing from a periodic stream, counted from its stamp gaps (StreamLoss)."""

from __future__ import annotations

import numpy as np

from hexapod_common.clocks import StreamLoss


def test_counts_each_dropped_message_of_a_jittered_1khz_stream():
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 20.0, 1e-3) + rng.normal(0.0, 5e-5, 20000)   # 5 % stamp jitter
    keep = rng.random(t.size) > 0.06
    keep[:20] = True
    loss = StreamLoss()
    got = [loss.observe('js', float(x)) for x in t[keep]]
    true = np.diff(np.flatnonzero(keep)) - 1
    assert loss.missing['js'] == true.sum()
    assert np.array_equal(got[1:], true)
    assert loss.seen['js'] == keep.sum()


def test_no_loss_counted_on_jitter_repeats_out_of_order_stamps_or_a_loop():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.007, 0.013, 3000))            # +-30 % jitter, nothing lost
    loss = StreamLoss()
    for x in t:
        loss.observe('b', float(x))
        loss.observe('b', float(x))                           # a repeated stamp
        loss.observe('b', float(x) - 0.004)                   # out of order
    for x in t[:100]:                                          # a looped bag starts again
        loss.observe('b', float(x))
    assert loss.total() == 0


def test_streams_apart_and_the_log_lines_thin_out():
    loss = StreamLoss()
    lines = []
    for k in range(2000):
        for group in ('left', 'right'):                       # one topic, two name groups
            if group == 'left' and k > 100 and k % 3 == 0:
                continue                                       # the left group loses a third
            note = loss.observe_topic('joint_states', group, 0.01 * k + 1e-4)
            if note:
                lines.append(note)
    assert loss.missing.get(('joint_states', 'right'), 0) == 0
    lost = loss.total('joint_states')
    assert lost == sum(1 for k in range(101, 2000) if k % 3 == 0)
    assert [x.split(':')[1].split()[0] for x in lines] == ['1', '10', '100']
    assert 'messages missing so far' in lines[0] and lines[0].startswith('joint_states:')
