"""Launch the glpma_fk node with a params file.

    ros2 launch glpma_ros fk.launch.py                      # 3-RPR, config/params_3rpr.yaml
    ros2 launch glpma_ros fk.launch.py manipulator:=hexapod # 6-6 hexapod, config/params_hexapod.yaml
    ros2 launch glpma_ros fk.launch.py params_file:=/path/to/my_params.yaml
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


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
        Node(
            package="glpma_ros",
            executable="fk_node",
            name="glpma_fk",
            output="screen",
            parameters=[LaunchConfiguration("params_file")],
        ),
    ])
