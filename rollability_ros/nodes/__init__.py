"""Thin rclpy adapters: one node per module, each with ``main(args=None)``; logic lives in ``core``."""
