"""A team run centrally, every robot's decentralized update in turn (``coverage-plan``), with
lidar scans simulated on the occupancy grid for the sensor-based strategies."""
