"""Cyclone DDS transport: ROS 2 message types as DDS IDL and the node over plain DDS.

Importing this package needs ``cyclonedds`` (not rclpy).
"""
