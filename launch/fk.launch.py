"""Launch the glpma_fk node with a params file, and RViz if asked.

    ros2 launch glpma_ros fk.launch.py                      # 3-RPR, config/params_3rpr.yaml
    ros2 launch glpma_ros fk.launch.py manipulator:=hexapod # 6-6 hexapod, config/params_hexapod.yaml
    ros2 launch glpma_ros fk.launch.py params_file:=/path/to/my_params.yaml
    ros2 launch glpma_ros fk.launch.py rviz:=true           # + rviz2 with config/glpma_fk.rviz (markers on)

``rviz:=true`` starts ``rviz2`` where it is installed and says so in the log where it is not
(the node runs either way); it also turns ``publish_markers`` on unless ``markers:=false``.
``markers:=true|false`` sets ``publish_markers`` whatever the params file says.
"""
from ament_index_python.packages import PackageNotFoundError, get_package_prefix
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

RVIZ_PACKAGE = "rviz2"


def rviz_if_installed(context, *args, **kwargs):
    """rviz2 with config/glpma_fk.rviz, or a log line when the rviz2 package is not installed."""
    try:
        get_package_prefix(RVIZ_PACKAGE)
    except PackageNotFoundError:
        return [LogInfo(msg="rviz:=true, but rviz2 is not installed (not in AMENT_PREFIX_PATH): "
                            "not starting it; the glpma_fk node runs without it")]
    config = PathJoinSubstitution([FindPackageShare("glpma_ros"), "config", "glpma_fk.rviz"])
    return [Node(package=RVIZ_PACKAGE, executable="rviz2", name="rviz2", output="screen",
                 arguments=["-d", config.perform(context)])]


def fk_node(context, *args, **kwargs):
    """The node with the params file, and ``publish_markers`` when markers:= or rviz:= ask for it."""
    parameters = [LaunchConfiguration("params_file").perform(context)]
    markers = LaunchConfiguration("markers").perform(context)
    if markers == "" and LaunchConfiguration("rviz").perform(context) == "true":
        markers = "true"
    if markers in ("true", "false"):
        parameters.append({"publish_markers": markers == "true"})
    return [Node(package="glpma_ros", executable="fk_node", name="glpma_fk", output="screen",
                 parameters=parameters)]


def generate_launch_description():
    manipulator = LaunchConfiguration("manipulator")
    default_params = PathJoinSubstitution([
        FindPackageShare("glpma_ros"), "config",
        PythonExpression(["'params_' + ('hexapod' if '", manipulator, "' == 'hexapod' else '3rpr') + '.yaml'"]),
    ])
    return LaunchDescription([
        DeclareLaunchArgument("manipulator", default_value="3rpr", choices=["3rpr", "hexapod"],
                              description="which shipped params file to use"),
        DeclareLaunchArgument("params_file", default_value=default_params,
                              description="ROS 2 params file of the glpma_fk node"),
        DeclareLaunchArgument("rviz", default_value="false", choices=["true", "false"],
                              description="start rviz2 with config/glpma_fk.rviz (where rviz2 is installed)"),
        DeclareLaunchArgument("markers", default_value="", choices=["", "true", "false"],
                              description="parameter publish_markers of the node (default: the params file's "
                                          "value, true with rviz:=true)"),
        OpaqueFunction(function=fk_node),
        OpaqueFunction(function=rviz_if_installed, condition=IfCondition(LaunchConfiguration("rviz"))),
    ])
