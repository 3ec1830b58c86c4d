"""Start register_node with config/frisicp.yaml; topics, names, log level and QoS are arguments.

ros2 launch frisicp_ros register.launch.py model_topic:=/map_cloud data_topic:=/lidar/points
ros2 launch frisicp_ros register.launch.py params_file:=/path/to/my.yaml namespace:=robot1
ros2 launch frisicp_ros register.launch.py model_qos:=transient_local log_level:=debug
ros2 launch frisicp_ros register.launch.py lifecycle:=true   # register_lifecycle_node, unconfigured

model_qos / data_qos left empty keep the parameter file's value (config/frisicp.yaml: sensor_data).
log_level applies to the node's own logger only (not rcl's or the middleware's).
large_messages_profile: the shipped Fast DDS profile (config/fastdds_large_messages.xml: shared
memory with a 32 MiB segment) for the node. "auto" (default) uses it where it helps and cannot
cut the node off: Fast DDS, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (everything on this machine;
the profile is shared memory only) and no profile of the user's (FASTRTPS_DEFAULT_PROFILES_FILE);
"true" uses it anyway (unless the user's own is set), "false" never.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node

from launch import LaunchDescription

# The QoS choices of the settings table (frisicp_ros/stream/settings.py); "" = the file's value.
MODEL_QOS_CHOICES = ["", "sensor_data", "reliable", "transient_local"]
DATA_QOS_CHOICES = ["", "sensor_data", "reliable"]
LOG_LEVELS = ["debug", "info", "warn", "error", "fatal"]
BOOLEANS = ["true", "false"]
PROFILE_CHOICES = ["auto", "true", "false"]
PROFILE_VARIABLE = "FASTRTPS_DEFAULT_PROFILES_FILE"


def logger_name(namespace, name):
    """rcl's logger name of a node: its namespace's parts, then its name, joined by dots."""
    return ".".join([part for part in namespace.split("/") if part] + [name])


def large_messages_env(choice, environ, share):
    """The environment the node gets for large_messages_profile ``choice`` (module doc)."""
    if choice == "false" or environ.get(PROFILE_VARIABLE):
        return {}
    fast_dds = environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp") == "rmw_fastrtps_cpp"
    on_this_machine = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").upper() == "LOCALHOST"
    if choice == "auto" and not (fast_dds and on_this_machine):
        return {}
    return {PROFILE_VARIABLE: os.path.join(share, "config", "fastdds_large_messages.xml")}


def start_node(context):
    """The node (plain or managed), with a QoS parameter only where the argument was given (so the
    file's value stays otherwise)."""
    overrides = {
        name: value
        for name in ("model_qos", "data_qos")
        if (value := LaunchConfiguration(name).perform(context))
    }
    name = LaunchConfiguration("node_name").perform(context)
    namespace = LaunchConfiguration("namespace").perform(context)
    level = LaunchConfiguration("log_level").perform(context)
    managed = LaunchConfiguration("lifecycle").perform(context) == "true"
    share = get_package_share_directory("frisicp_ros")
    env = large_messages_env(
        LaunchConfiguration("large_messages_profile").perform(context), os.environ, share
    )
    node_class = LifecycleNode if managed else Node
    return [
        node_class(
            package="frisicp_ros",
            executable="register_lifecycle_node" if managed else "register_node",
            name=name,
            namespace=namespace,
            output="screen",
            parameters=[LaunchConfiguration("params_file"), *([overrides] if overrides else [])],
            remappings=[
                ("model", LaunchConfiguration("model_topic")),
                ("data", LaunchConfiguration("data_topic")),
            ],
            # Only the node's logger: a bare --log-level would also turn on rcl's and the RMW's.
            arguments=["--ros-args", "--log-level", f"{logger_name(namespace, name)}:={level}"],
            additional_env=env or None,
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
                "log_level",
                default_value="info",
                choices=LOG_LEVELS,
                description="log level of the node's own logger (rcl and the middleware keep theirs)",
            ),
            DeclareLaunchArgument(
                "lifecycle",
                default_value="false",
                choices=BOOLEANS,
                description="true: register_lifecycle_node, a managed node that starts unconfigured",
            ),
            DeclareLaunchArgument(
                "large_messages_profile",
                default_value="auto",
                choices=PROFILE_CHOICES,
                description="the shipped Fast DDS profile for large clouds (shared memory only): auto ="
                " when everything is on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) and no"
                " profile of yours is set",
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
