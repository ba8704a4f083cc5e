"""ament_python package setup for coverage_ros (colcon build, pip install -e .)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "coverage_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.rviz")),
        (f"share/{PACKAGE}/config/teams", glob("config/teams/*.yaml")),
        (f"share/{PACKAGE}/config/worlds", glob("config/worlds/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="coverage_ros maintainers",
    maintainer_email="coverage-ros@example.org",
    description="Decentralized multi-robot Voronoi coverage for ROS 2 Jazzy",
    license="Apache-2.0",
    python_requires=">=3.10",
    entry_points={
        "console_scripts": [
            "world_node = coverage_ros.nodes.world_node:main",
            "robot_node = coverage_ros.nodes.robot_node:main",
            "robot_container = coverage_ros.nodes.robot_container:main",
            "coverage-plan = coverage_ros.cli.plan:main",
            "rerun_bridge = coverage_ros.nodes.rerun_bridge:main",
            "marker_node = coverage_ros.nodes.marker_node:main",
            "coverage-team = coverage_ros.cli.team:main",
            "coverage-teleop = coverage_ros.cli.teleop:main",
        ],
    },
)
