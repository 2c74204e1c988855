"""lomanip_perception: Perception: prompts and RGB-D to 3D contacts per subtask."""
from glob import glob

from setuptools import find_packages, setup

setup(
    name="lomanip_perception",
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={"lomanip_perception": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/lomanip_perception"]),
        ("share/lomanip_perception", ["package.xml"]),
        ("share/lomanip_perception/config", glob("config/*.yaml")),
    ],
    include_package_data=True,
    zip_safe=False,
    python_requires=">=3.10",
    entry_points={"console_scripts": []},
)
