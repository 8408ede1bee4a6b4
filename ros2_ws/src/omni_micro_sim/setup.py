from setuptools import find_packages, setup

package_name = 'omni_micro_sim'

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
    description=('Slip dynamics of the tri-wheeled omnidirectional microrobot (Jin, Chen and '
                 'Li, ICIRA 2008) and the node that integrates them.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'dynamics_node = omni_micro_sim.dynamics_node:main',
        ],
    },
)
