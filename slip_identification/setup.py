from setuptools import find_packages, setup

package_name = 'slip_identification'

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
    description='Preprocessing, stance extraction, SLIP model and per-stance fits; SLIP node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'slip_fitter = slip_identification.slip_node:main',
        ],
    },
)
