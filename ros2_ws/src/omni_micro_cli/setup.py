from setuptools import find_packages, setup

package_name = 'omni_micro_cli'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={'omni_micro_cli.commands.study': ['example.yaml']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='omni-micro developers',
    maintainer_email='dev@omni-micro.invalid',
    description=('The omni-micro command line: runs (through omni_micro_bringup), studies, '
                 'figures, bags and benchmarks.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'omni-micro = omni_micro_cli.cli:command',
        ],
    },
)
