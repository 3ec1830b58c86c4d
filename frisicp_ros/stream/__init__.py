"""The message stream without ROS: PointCloud2 conversion, pairing, the registration pipeline,
output messages and the settings table. Nothing here imports rclpy; messages are duck-typed, so
rclpy messages (the node) and rosbags messages (the bag mode) go through the same code.
"""
