"""lomanip_sim: MuJoCo world of the G1 in the paper's scenarios, RGB-D camera, standing controller and the simulation node."""
from glob import glob

from setuptools import find_packages, setup

setup(
    name="lomanip_sim",
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={"lomanip_sim": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/lomanip_sim"]),
        ("share/lomanip_sim", ["package.xml"]),
        ("share/lomanip_sim/config", glob("config/*.yaml")),
    ],
    include_package_data=True,
    zip_safe=False,
    python_requires=">=3.10",
    entry_points={"console_scripts": ["lomanip_sim_node = lomanip_sim.sim_node:main"]},
)
