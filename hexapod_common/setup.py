from setuptools import find_packages, setup

package_name = 'hexapod_common'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed', '*.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hexapod-energetics maintainers',
    maintainer_email='maintainers@hexapod-energetics.invalid',
    description='Shared node conventions, message conversions, rosbag2 record/replay and the offline replay harness.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'bag_recorder = hexapod_common.recorder_node:main',
        'bag_replay = hexapod_common.replay_node:main',
        'hexapod-demo = hexapod_common.demo:main',
        'hexapod-analyze = hexapod_common.analyze_cli:main',
        ],
    },
)
