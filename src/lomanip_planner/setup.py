"""lomanip_planner: Retargeting, keyframes, contact schedule and the plan service."""
from glob import glob

from setuptools import find_packages, setup

setup(
    name="lomanip_planner",
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={"lomanip_planner": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/lomanip_planner"]),
        ("share/lomanip_planner", ["package.xml"]),
        ("share/lomanip_planner/config", glob("config/*.yaml")),
    ],
    include_package_data=True,
    zip_safe=False,
    python_requires=">=3.10",
    entry_points={"console_scripts": ["lomanip_planner_node = lomanip_planner.planner_node:main"]},
)
