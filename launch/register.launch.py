"""Start register_node with config/frisicp.yaml; the two input topics are launch arguments.

ros2 launch frisicp_ros register.launch.py model_topic:=/map_cloud data_topic:=/lidar/points
ros2 launch frisicp_ros register.launch.py params_file:=/path/to/my.yaml
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory("frisicp_ros"), "config", "frisicp.yaml")
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "model_topic",
                default_value="model",
                description="sensor_msgs/PointCloud2 topic of the model (map) cloud",
            ),
            DeclareLaunchArgument(
                "data_topic",
                default_value="data",
                description="sensor_msgs/PointCloud2 topic of the data (scan) clouds",
            ),
            DeclareLaunchArgument(
                "params_file", default_value=default_params, description="parameter file of the node"
            ),
            Node(
                package="frisicp_ros",
                executable="register_node",
                name="frisicp",
                output="screen",
                parameters=[LaunchConfiguration("params_file")],
                remappings=[
                    ("model", LaunchConfiguration("model_topic")),
                    ("data", LaunchConfiguration("data_topic")),
                ],
            ),
        ]
    )
