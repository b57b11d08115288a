from setuptools import find_packages, setup

package_name = 'hexapod_energy'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='hexapod-energetics maintainers',
    maintainer_email='maintainers@hexapod-energetics.invalid',
    description='Energetic descriptors, single-leg method, inverse dynamics, sweeps, optimal operating points, residual loop; energy node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'energy_monitor = hexapod_energy.energy_node:main',
        ],
    },
)
