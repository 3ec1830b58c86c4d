"""Start register_node with config/frisicp.yaml; topics, names, log level and QoS are arguments.

ros2 launch frisicp_ros register.launch.py model_topic:=/map_cloud data_topic:=/lidar/points
ros2 launch frisicp_ros register.launch.py params_file:=/path/to/my.yaml namespace:=robot1
ros2 launch frisicp_ros register.launch.py model_qos:=transient_local log_level:=debug

model_qos / data_qos left empty keep the parameter file's value (config/frisicp.yaml: sensor_data).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription

# The QoS choices of the settings table (frisicp_ros/stream/settings.py); "" = the file's value.
MODEL_QOS_CHOICES = ["", "sensor_data", "reliable", "transient_local"]
DATA_QOS_CHOICES = ["", "sensor_data", "reliable"]
LOG_LEVELS = ["debug", "info", "warn", "error", "fatal"]


def start_node(context):
    """The node, with a QoS parameter only where the argument was given (so the file's value
    stays otherwise)."""
    overrides = {
        name: value
        for name in ("model_qos", "data_qos")
        if (value := LaunchConfiguration(name).perform(context))
    }
    return [
        Node(
            package="frisicp_ros",
            executable="register_node",
            name=LaunchConfiguration("node_name"),
            namespace=LaunchConfiguration("namespace"),
            output="screen",
            parameters=[LaunchConfiguration("params_file"), *([overrides] if overrides else [])],
            remappings=[
                ("model", LaunchConfiguration("model_topic")),
                ("data", LaunchConfiguration("data_topic")),
            ],
            arguments=["--ros-args", "--log-level", LaunchConfiguration("log_level")],
        )
    ]


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
            DeclareLaunchArgument("namespace", default_value="", description="namespace of the node"),
            DeclareLaunchArgument(
                "node_name", default_value="frisicp", description="name of the node (its topics are ~/...)"
            ),
            DeclareLaunchArgument(
                "log_level", default_value="info", choices=LOG_LEVELS, description="the node's log level"
            ),
            DeclareLaunchArgument(
                "model_qos",
                default_value="",
                choices=MODEL_QOS_CHOICES,
                description="QoS of the model subscription (transient_local for a latched map);"
                " empty = the parameter file's",
            ),
            DeclareLaunchArgument(
                "data_qos",
                default_value="",
                choices=DATA_QOS_CHOICES,
                description="QoS of the data subscription; empty = the parameter file's",
            ),
            OpaqueFunction(function=start_node),
        ]
    )
