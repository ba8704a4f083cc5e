"""The pymunk world simulator: static geometry, differential-drive robots and lidar (no rclpy).

See :mod:`coverage_ros.sim.world` for the entry point (:class:`~coverage_ros.sim.world.World`).
"""
