"""Thin rclpy nodes: parameters in, messages converted, core called, results published."""
