from setuptools import find_packages, setup

package_name = 'omni_micro_control'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='omni-micro developers',
    maintainer_email='dev@omni-micro.invalid',
    description=('Vision-feedback controller of section 4: timer1/timer2, angle modifier, '
                 'distance comparator.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'controller_node = omni_micro_control.controller_node:main',
        ],
    },
)
