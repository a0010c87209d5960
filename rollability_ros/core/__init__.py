"""The pure core: geometry, physics, optimiser, campaign, analysis, bags, hardware. Never imports rclpy."""
