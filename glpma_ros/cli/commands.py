"""The built-in commands of ``glpma-fk``, registered in setup.py's entry-point group ``glpma_fk.commands``
as the tools' commands are (``"solve = glpma_ros.cli.commands:SOLVE"``).  Each one's code is its own
module, imported when it runs."""
from .api import Command

SOLVE = Command("solve one set of leg lengths", "glpma_ros.cli.solve:main")
SOLVE_ALL = Command("every distinct real assembly mode", "glpma_ros.cli.solve_all:main")
PRECOMPILE = Command("compile every solver ahead of time (run once after installing)", "glpma_ros.cli.precompile:main")
MODES = Command("ask a running node for every assembly mode of its last input", "glpma_ros.cli.modes:main")
CALIBRATE = Command("the real geometry (joints, leg offsets) from measured poses", "glpma_ros.calibration:main")
NODE = Command("run the estimator node (rclpy or Cyclone DDS)", "glpma_ros.node.entry:main")
URDF = Command("the manipulator's URDF (loop-cut tree) for robot_state_publisher and RViz", "glpma_ros.cli.urdf:main")
