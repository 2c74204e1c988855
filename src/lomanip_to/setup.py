"""lomanip_to: Whole-body trajectory optimisation for the G1: centroidal dynamics with full kinematics."""
from glob import glob

from setuptools import find_packages, setup

setup(
    name="lomanip_to",
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={"lomanip_to": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/lomanip_to"]),
        ("share/lomanip_to", ["package.xml"]),
        ("share/lomanip_to/config", glob("config/*.yaml")),
    ],
    include_package_data=True,
    zip_safe=False,
    python_requires=">=3.10",
    entry_points={"console_scripts": ["lomanip_to_node = lomanip_to.to_node:main"]},
)
