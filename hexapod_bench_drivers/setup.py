from setuptools import find_packages, setup

package_name = 'hexapod_bench_drivers'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', ['config/dynamixel_driver.yaml',
                                               'config/hexapod_ax18a_joints.yaml',
                                               'config/bench_plan.yaml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hexapod-energetics maintainers',
    maintainer_email='maintainers@hexapod-energetics.invalid',
    description='Dynamixel servos, power monitor, force sensor, bench sequencer, servo-bus emulator and physics simulators.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'dynamixel_driver = hexapod_bench_drivers.dynamixel_node:main',
        'power_monitor = hexapod_bench_drivers.power_node:main',
        'force_sensor = hexapod_bench_drivers.force_node:main',
        'bench_sequencer = hexapod_bench_drivers.sequencer_node:main',
        'sim_robot = hexapod_bench_drivers.sim_nodes:main_robot',
        'sim_bench = hexapod_bench_drivers.sim_nodes:main_bench',
        'hexapod-sim = hexapod_bench_drivers.sim_cli:main',
        ],
    },
)
