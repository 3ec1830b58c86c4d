"""frisicp_ros: the ROS 2 side of frisicp (node, PointCloud2 conversion, bag mode, CLI).

Importing this package never imports rclpy: the CLI and the bag mode work without ROS.
"""
