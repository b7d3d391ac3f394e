"""Launch the glpma_fk node with a params file, and RViz if asked.

    ros2 launch glpma_ros fk.launch.py                      # 3-RPR, config/params_3rpr.yaml
    ros2 launch glpma_ros fk.launch.py manipulator:=hexapod # 6-6 hexapod, config/params_hexapod.yaml
    ros2 launch glpma_ros fk.launch.py manipulator:=delta   # rotary Delta, config/params_delta.yaml
    ros2 launch glpma_ros fk.launch.py params_file:=/path/to/my_params.yaml
    ros2 launch glpma_ros fk.launch.py rviz:=true           # + rviz2 with config/glpma_fk.rviz (markers on)
    ros2 launch glpma_ros fk.launch.py robot_description:=true rviz:=true   # + robot_state_publisher: the robot
    ros2 launch glpma_ros fk.launch.py managed:=true        # fk_lifecycle_node, driven by ros2 lifecycle set
    ros2 launch glpma_ros fk.launch.py managed:=true autostart:=true   # ... configured and activated at once
    ros2 launch glpma_ros fk.launch.py secure:=true keystore:=$HOME/glpma_keystore   # SROS2, enclave /glpma_fk

``managed:=true`` runs the managed node (same name, parameters and topics; it starts unconfigured).
``input_type:=joint_state|float64_multi_array`` sets ``input_type`` whatever the params file says.
``secure:=true`` starts the node with ``ROS_SECURITY_ENABLE=true``, ``ROS_SECURITY_STRATEGY=Enforce``,
``ROS_SECURITY_KEYSTORE=<keystore>`` and ``--enclave <enclave>`` (default ``/glpma_fk``): README,
"Running secured".
``rviz:=true`` starts ``rviz2`` where it is installed and says so in the log where it is not
(the node runs either way); it also turns ``publish_markers`` on unless ``markers:=false``.
``markers:=true|false`` sets ``publish_markers`` whatever the params file says.
``robot_description:=true`` writes the URDF of the node's ``manipulator_config`` (``glpma-fk urdf``, with
the params file's ``urdf_prefix``), starts ``robot_state_publisher`` with it, fed by the node's
``~/mechanism_joint_states`` (``publish_joint_states:=true``), and gives the node the URDF's frames
(``frame_id:=<prefix>base_link``, ``child_frame_id:=<prefix>platform_link``) with ``publish_tf:=false``:
``robot_state_publisher`` broadcasts base_link -> ... -> platform_link, one publisher per transform.
Where ``robot_state_publisher`` is not installed the launch says so in one line and the node runs
without it (its own /tf on).  With ``rviz:=true`` RViz's fixed frame is then ``<prefix>base_link``.
"""
from ament_index_python.packages import PackageNotFoundError, get_package_prefix
from launch.actions import DeclareLaunchArgument, EmitEvent, LogInfo, OpaqueFunction, RegisterEventHandler
from launch.conditions import IfCondition
from launch.events import matches_action
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import LifecycleNode, Node
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from launch_ros.substitutions import FindPackageShare
from lifecycle_msgs.msg import Transition

from launch import LaunchDescription

RVIZ_PACKAGE = "rviz2"
RSP_PACKAGE = "robot_state_publisher"
#: the node's parameters in a params file
NODE_KEYS = ("glpma_fk", "/glpma_fk", "/**")
#: where robot_state_publisher reads the joint states (the node's private topic, not /joint_states:
#: with input_type:=joint_state the node reads joint_states itself)
MECHANISM_JOINT_STATES = "/glpma_fk/mechanism_joint_states"
#: robot_state_publisher forwards at most this many joint states a second to /tf (its default, 20, drops
#: poses: /tf at a pose's stamp would then be interpolated between others); the node answers up to 1 kHz
RSP_PUBLISH_FREQUENCY_HZ = 1000.0


def installed(package: str) -> bool:
    try:
        get_package_prefix(package)
    except PackageNotFoundError:
        return False
    return True


def params_file_value(path: str, name: str, default):
    """Parameter ``name`` of the glpma_fk node in the params file ``path`` (or ``default``)."""
    import yaml
    try:
        with open(path) as f:
            doc = yaml.safe_load(f) or {}
    except OSError:
        return default
    for key in NODE_KEYS:
        values = (doc.get(key) or {}).get("ros__parameters") or {}
        if name in values:
            return values[name]
    return default


def description_wanted(context) -> bool:
    """robot_description:=true and robot_state_publisher installed."""
    return LaunchConfiguration("robot_description").perform(context) == "true" and installed(RSP_PACKAGE)


def urdf_prefix(context) -> str:
    return str(params_file_value(LaunchConfiguration("params_file").perform(context), "urdf_prefix", ""))


def robot_state_publisher(context, *args, **kwargs):
    """robot_state_publisher with the URDF of the node's manipulator_config, or one log line when it is
    not installed."""
    if not installed(RSP_PACKAGE):
        return [LogInfo(msg="robot_description:=true, but robot_state_publisher is not installed (not in "
                            "AMENT_PREFIX_PATH): not starting it; the glpma_fk node runs with its own /tf")]
    from glpma_ros.config import load_manipulator, resolve_config
    from glpma_ros.description.urdf import urdf_text
    params = LaunchConfiguration("params_file").perform(context)
    config = LaunchConfiguration("manipulator_config").perform(context) or \
        str(params_file_value(params, "manipulator_config", "planar_3rpr_seed"))
    path = resolve_config(config)
    model = load_manipulator(path)
    text = urdf_text(model, robot_name=path.stem, prefix=urdf_prefix(context), source=path.name)
    return [Node(package=RSP_PACKAGE, executable="robot_state_publisher", name="robot_state_publisher",
                 output="screen", parameters=[{"robot_description": text,
                                               "publish_frequency": RSP_PUBLISH_FREQUENCY_HZ}],
                 remappings=[("joint_states", MECHANISM_JOINT_STATES)])]


def rviz_if_installed(context, *args, **kwargs):
    """rviz2 with config/glpma_fk.rviz, or a log line when the rviz2 package is not installed."""
    if not installed(RVIZ_PACKAGE):
        return [LogInfo(msg="rviz:=true, but rviz2 is not installed (not in AMENT_PREFIX_PATH): "
                            "not starting it; the glpma_fk node runs without it")]
    config = PathJoinSubstitution([FindPackageShare("glpma_ros"), "config", "glpma_fk.rviz"])
    arguments = ["-d", config.perform(context)]
    if description_wanted(context):
        arguments += ["--fixed-frame", urdf_prefix(context) + "base_link"]
    return [Node(package=RVIZ_PACKAGE, executable="rviz2", name="rviz2", output="screen", arguments=arguments)]


def fk_node(context, *args, **kwargs):
    """The node (managed or not) with the params file, ``publish_markers`` when markers:= or rviz:=
    ask for it, ``input_type`` when input_type:= is given, and the SROS2 environment with secure:=true."""
    def arg(name):
        return LaunchConfiguration(name).perform(context)

    parameters = [arg("params_file")]
    markers = arg("markers")
    if markers == "" and arg("rviz") == "true":
        markers = "true"
    if markers in ("true", "false"):
        parameters.append({"publish_markers": markers == "true"})
    if arg("input_type"):
        parameters.append({"input_type": arg("input_type")})
    if arg("manipulator_config"):
        parameters.append({"manipulator_config": arg("manipulator_config")})
    if description_wanted(context):      # robot_state_publisher broadcasts the URDF's frames instead
        prefix = urdf_prefix(context)
        parameters.append({"publish_joint_states": True, "publish_tf": False, "frame_id": prefix + "base_link",
                           "child_frame_id": prefix + "platform_link"})
    options = dict(package="glpma_ros", name="glpma_fk", output="screen", parameters=parameters)
    if arg("secure") == "true":
        if not arg("keystore"):
            raise RuntimeError("secure:=true needs keystore:=DIR (a keystore from ros2 security create_keystore "
                               "with an enclave made by ros2 security create_enclave DIR " + arg("enclave") + ")")
        options.update(ros_arguments=["--enclave", arg("enclave")],
                       additional_env={"ROS_SECURITY_KEYSTORE": arg("keystore"), "ROS_SECURITY_ENABLE": "true",
                                       "ROS_SECURITY_STRATEGY": "Enforce"})
    if arg("managed") != "true":
        return [Node(executable="fk_node", **options)]
    node = LifecycleNode(executable="fk_lifecycle_node", namespace="", **options)
    if arg("autostart") != "true":
        return [node]

    def transition(transition_id):
        return EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node), transition_id=transition_id))
    return [node,
            RegisterEventHandler(OnStateTransition(target_lifecycle_node=node, goal_state="inactive",
                                                   entities=[transition(Transition.TRANSITION_ACTIVATE)])),
            transition(Transition.TRANSITION_CONFIGURE)]


def generate_launch_description():
    manipulator = LaunchConfiguration("manipulator")
    default_params = PathJoinSubstitution([
        FindPackageShare("glpma_ros"), "config",
        PythonExpression(["'params_' + '", manipulator, "' + '.yaml'"]),
    ])
    return LaunchDescription([
        DeclareLaunchArgument("manipulator", default_value="3rpr", choices=["3rpr", "hexapod", "delta"],
                              description="which shipped params file to use"),
        DeclareLaunchArgument("params_file", default_value=default_params,
                              description="ROS 2 params file of the glpma_fk node"),
        DeclareLaunchArgument("rviz", default_value="false", choices=["true", "false"],
                              description="start rviz2 with config/glpma_fk.rviz (where rviz2 is installed)"),
        DeclareLaunchArgument("markers", default_value="", choices=["", "true", "false"],
                              description="parameter publish_markers of the node (default: the params file's "
                                          "value, true with rviz:=true)"),
        DeclareLaunchArgument("input_type", default_value="", choices=["", "float64_multi_array", "joint_state"],
                              description="parameter input_type of the node (default: the params file's value)"),
        DeclareLaunchArgument("managed", default_value="false", choices=["true", "false"],
                              description="run fk_lifecycle_node (a managed node, starts unconfigured) "
                                          "instead of fk_node"),
        DeclareLaunchArgument("autostart", default_value="false", choices=["true", "false"],
                              description="with managed:=true: configure and activate the node at once"),
        DeclareLaunchArgument("secure", default_value="false", choices=["true", "false"],
                              description="run the node under SROS2 (DDS-Security, Enforce) with keystore:= "
                                          "and enclave:="),
        DeclareLaunchArgument("keystore", default_value="",
                              description="with secure:=true: the keystore directory (ros2 security create_keystore)"),
        DeclareLaunchArgument("enclave", default_value="/glpma_fk",
                              description="with secure:=true: the node's enclave in the keystore"),
        DeclareLaunchArgument("manipulator_config", default_value="",
                              description="parameter manipulator_config of the node (default: the params file's "
                                          "value)"),
        DeclareLaunchArgument("robot_description", default_value="false", choices=["true", "false"],
                              description="start robot_state_publisher with the URDF of manipulator_config (glpma-fk "
                                          "urdf), fed by the node's ~/mechanism_joint_states"),
        OpaqueFunction(function=fk_node),
        OpaqueFunction(function=robot_state_publisher, condition=IfCondition(LaunchConfiguration("robot_description"))),
        OpaqueFunction(function=rviz_if_installed, condition=IfCondition(LaunchConfiguration("rviz"))),
    ])
