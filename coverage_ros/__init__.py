"""coverage_ros: decentralized multi-robot Voronoi coverage for ROS 2 Jazzy."""

__version__ = "0.1.0"
