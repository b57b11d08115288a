"""Benchmark of BagWriter's split flush over a long recording: the cost of closing one split
(what bag_recorder does every second) after 10 and after 2,000 splits, against the
straightforward baseline it replaced, ruamel's YAML dump of the merged metadata, measured on
the same metadata in the same run.  Run: ``python bench/bench_recorder_splits.py [N]``.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from io import StringIO
from pathlib import Path

from ruamel.yaml import YAML

from hexapod_common.bags import BagWriter, new_msg, stamp


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    with tempfile.TemporaryDirectory() as tmp:
        w = BagWriter(Path(tmp) / 'bag')
        flush_ms: list[float] = []
        t = 1_000_000_000
        for _ in range(n):
            msg = new_msg('sensor_msgs/msg/BatteryState', header=stamp(t), voltage=12.0,
                          current=-1.0)
            w.write('/battery_state', 'sensor_msgs/msg/BatteryState', msg, t)
            t += 1_000_000_000
            t0 = time.perf_counter()
            w.flush()
            flush_ms.append(1e3 * (time.perf_counter() - t0))
        merged = w._merged
        yaml = YAML(typ='safe')
        yaml.default_flow_style = False
        t0 = time.perf_counter()
        out = StringIO()
        yaml.dump({'rosbag2_bagfile_information': merged}, out)
        ruamel_ms = 1e3 * (time.perf_counter() - t0)
    early = statistics.median(flush_ms[:10])
    late = statistics.median(flush_ms[-10:])
    print(f'split flush: {early:.1f} ms after 10 splits, {late:.1f} ms after {n} '
          f'(ratio {late / early:.2f})')
    print(f'baseline: ruamel YAML dump of the metadata of {n} splits alone: {ruamel_ms:.0f} ms '
          f'({ruamel_ms / late:.0f}x a whole flush now)')


if __name__ == '__main__':
    main()
