# catkin_python_setup() installs the node's Python package (never run by hand)
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["uavarm_link"], package_dir={"": "src"}))
