from setuptools import find_packages, setup

package_name = 'omni_micro_tools'

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
    description=('Nodes that watch the omni-micro graph: the bag recorder and the '
                 'Foxglove live view.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'bag_recorder = omni_micro_tools.recorder_node:main',
            'viewer = omni_micro_tools.viewer_node:main',
        ],
    },
)
