"""Every core module imports with rclpy (and every ROS message package) made unimportable.

The ROS layer is the node modules (``*_node.py``, ``*_nodes.py``) and the few shared modules
that exist to talk to ROS; everything else is science or I/O and must not need ROS.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ('hexapod_common', 'hexapod_gait', 'hexapod_bench_drivers', 'hexapod_energy',
            'slip_identification')
#: shared modules whose job is ROS itself (nodes, node conventions, replay through nodes)
ROS_LAYER = {'hexapod_common.node_utils', 'hexapod_common.recorder_node',
             'hexapod_common.replay_node', 'hexapod_common.spine_source',
             'hexapod_common.demo'}
BLOCKED = ('rclpy', 'rosidl_runtime_py', 'sensor_msgs', 'geometry_msgs', 'std_msgs',
           'hexapod_interfaces', 'rosgraph_msgs', 'diagnostic_msgs', 'std_srvs',
           'rcl_interfaces', 'builtin_interfaces')


def core_modules() -> list[str]:
    names = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg / pkg).glob('*.py')):
            mod = f'{pkg}.{path.stem}' if path.stem != '__init__' else pkg
            if path.stem.endswith(('_node', '_nodes')) or mod in ROS_LAYER:
                continue
            names.append(mod)
    return names


def test_core_modules_do_not_import_ros():
    modules = core_modules()
    assert len(modules) > 40
    script = f'''
import importlib, importlib.abc, sys
BLOCKED = {BLOCKED!r}
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in BLOCKED:
            raise ImportError(f'{{name}} is blocked: core must not need ROS')
        return None
sys.meta_path.insert(0, Block())
failed = []
for mod in {modules!r}:
    try:
        importlib.import_module(mod)
    except ImportError as err:
        failed.append(f'{{mod}}: {{err}}')
print('\\n'.join(failed))
sys.exit(1 if failed else 0)
'''
    proc = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          timeout=300, cwd='/')
    assert proc.returncode == 0, proc.stdout + proc.stderr
