from setuptools import find_packages, setup

package_name = 'omni_micro_vision'

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
    description=('Macro and micro overhead camera model: stationary pose captures with pixel '
                 'noise; markers of the run for RViz 2 and Foxglove.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'vision_node = omni_micro_vision.vision_node:main',
            'markers_node = omni_micro_vision.markers_node:main',
            'tracker_node = omni_micro_vision.tracker_node:main',
            'camera_node = omni_micro_vision.camera_node:main',
        ],
    },
)
