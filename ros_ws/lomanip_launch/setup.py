"""lomanip_launch: Orchestrator of the lomanip graph: starts the nodes, records rosbag2 bags, summarises them."""
from glob import glob

from setuptools import find_packages, setup

setup(
    name="lomanip_launch",
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={"lomanip_launch": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/lomanip_launch"]),
        ("share/lomanip_launch", ["package.xml"]),
        ("share/lomanip_launch/config", glob("config/*.yaml")),
    ],
    include_package_data=True,
    zip_safe=False,
    python_requires=">=3.10",
    entry_points={"console_scripts": ["lomanip = lomanip_launch.cli:main", "lomanip_recorder = lomanip_launch.recorder_node:main"]},
)
