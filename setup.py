"""ament_python package definition (colcon build or pip install)."""

import ast
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "pdsmc_ros"


def builtin_entry_points() -> dict[str, list[str]]:
    """The built-in laws and robots as entry points (groups ``pdsmc_ros.laws``, ``pdsmc_ros.robots``),
    read from their one declaration, pdsmc_ros/plugins.py's BUILTIN_ENTRY_POINTS (a literal: read
    without importing the package)."""
    tree = ast.parse((Path(__file__).parent / PACKAGE / "plugins.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["BUILTIN_ENTRY_POINTS"]:
            return ast.literal_eval(node.value)
    raise SystemExit("setup.py: pdsmc_ros/plugins.py declares no BUILTIN_ENTRY_POINTS")


setup(
    name=PACKAGE,
    version="0.1.0",
    # config/ and scripts/ also ship inside the package (pdsmc_ros/data/...), so the core
    # finds them with importlib.resources and no ROS environment (pdsmc_ros/resources.py)
    packages=find_packages(exclude=["test", "test.*"]) + [f"{PACKAGE}.data.config", f"{PACKAGE}.data.scripts"],
    package_dir={f"{PACKAGE}.data.config": "config", f"{PACKAGE}.data.scripts": "scripts"},
    package_data={
        PACKAGE: ["py.typed"],
        f"{PACKAGE}.data.config": ["*.yaml", "*.xml", "urdf/*.urdf", "urdf/*.yaml"],
        f"{PACKAGE}.data.scripts": ["*.sh"],
    },
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", sorted(glob("config/*.yaml")) + sorted(glob("config/*.xml"))),
        (f"share/{PACKAGE}/config/urdf", sorted(glob("config/urdf/*"))),
        (f"share/{PACKAGE}/scripts", sorted(glob("scripts/*.sh"))),
    ],
    install_requires=["setuptools", "numpy", "PyYAML", "numba", "rosbags", "mcap", "pin", "example-robot-data",
                      "foxglove-sdk", "dask[distributed]"],
    zip_safe=True,
    maintainer="pdsmc_ros developers",
    maintainer_email="pdsmc_ros@example.org",
    description="Hybrid PD sliding mode control for robotic manipulators on ROS 2",
    license="Apache-2.0",
    python_requires=">=3.10",
    entry_points={
        "console_scripts": [
            "pdsmc = pdsmc_ros.cli:main",
            "ros2 = pdsmc_ros.cli.ros2:main",
            "plant = pdsmc_ros.plant.node:main",
            "trajectory = pdsmc_ros.trajectory.node:main",
            "controller = pdsmc_ros.controller.node:main",
            "recorder = pdsmc_ros.recorder.node:main",
            "composed = pdsmc_ros.composed.container:main",
            "viewer = pdsmc_ros.viewer.node:main",
            "mujoco_driver = pdsmc_ros.mujoco_driver.node:main",
            "analyze = pdsmc_ros.cli:analyze_main",
        ],
        **builtin_entry_points(),
    },
)
