"""The manipulator as ROS describes robots: the URDF of its loop-cut tree and every joint's state at
a pose (:mod:`.mechanism`, :mod:`.urdf`), and the passive joints' limits (:mod:`.limits`).  No ROS import."""
