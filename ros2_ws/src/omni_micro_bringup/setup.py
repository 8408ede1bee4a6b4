from glob import glob

from setuptools import find_packages, setup

package_name = 'omni_micro_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='omni-micro developers',
    maintainer_email='dev@omni-micro.invalid',
    description=('The omni-micro graph brought up: its composition, processes, supervision '
                 'and outcome.'),
    license='Apache-2.0',
)
