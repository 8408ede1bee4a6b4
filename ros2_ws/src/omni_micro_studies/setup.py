from setuptools import find_packages, setup

package_name = 'omni_micro_studies'

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
    description=('The twin (the node graph\'s loop in one process, one robot or several) and '
                 'the study engine that runs it by the thousand on Dask.'),
    license='Apache-2.0',
)
