"""Package layout, read by pip (with the metadata of pyproject.toml) and by
catkin_python_setup(), which makes the devel space's `dynaorb` package (where
the generated dynaorb.srv lands) a relay to python/dynaorb."""
from setuptools import find_packages, setup

setup(version="0.1.0",  # also in pyproject.toml and package.xml (catkin checks it)
      packages=find_packages("python"), package_dir={"": "python"},
      package_data={"dynaorb": ["_core*.so"]})
