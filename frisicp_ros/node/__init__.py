"""The ROS 2 node ``register_node`` (``node``), its parameters, status and bag replay, and the demo.

Only ``node``, ``parameters`` and ``replay`` import rclpy; importing this package does not.
"""
