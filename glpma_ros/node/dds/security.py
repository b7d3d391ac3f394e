"""SROS2 (DDS-Security) and the Cyclone DDS transport: never unsecured when security was asked for.

ROS 2 turns security on for a process with ``ROS_SECURITY_ENABLE=true`` (rcl compares the value with
``true`` exactly) and finds its certificates in ``ROS_SECURITY_KEYSTORE`` under the enclave given by
``--enclave`` (ROS 2 design, *ROS 2 DDS-Security integration*).  The rclpy node gets all of that from
rcl and ``rmw_cyclonedds_cpp`` (README, "Running secured").

The Cyclone DDS transport cannot: the ``cyclonedds`` Python binding from PyPI (11.0.1, the version
this package installs) ships a ``libddsc`` built without DDS-Security -- it exports none of the
``DDS_Security_*`` functions a security-enabled build has and brings no authentication, access-control
or cryptography plugin (``libdds_security_{auth,ac,crypto}``) -- so a participant it creates cannot
authenticate; the binding loads its own ``libddsc``, not the security-enabled one of a ROS 2 Jazzy
installation (Cyclone DDS 0.10.5).  :func:`check_dds_transport` therefore refuses to start any Cyclone DDS participant
of this
package (the node, ``glpma-fk modes``, the tools) when security is enabled, with one line saying so:
it never joins unsecured a domain whose operator asked for security.
"""
from __future__ import annotations

import os

from ...errors import InputError

#: the environment variable and the value with which ROS 2 enables security (rcl: exact match)
SECURITY_ENABLE_VAR, SECURITY_ENABLED = "ROS_SECURITY_ENABLE", "true"


def security_enabled(environ=None) -> bool:
    """Is SROS2 enabled for this process, as rcl decides it?"""
    return (os.environ if environ is None else environ).get(SECURITY_ENABLE_VAR) == SECURITY_ENABLED


def check_dds_transport(environ=None) -> None:
    """:class:`InputError` (one line) when security is enabled: the Cyclone DDS transport cannot join
    a secured domain (module docstring)."""
    if security_enabled(environ):
        raise InputError(f"{SECURITY_ENABLE_VAR}=true, but the Cyclone DDS transport cannot join a secured ROS 2 "
                         "domain (the cyclonedds Python binding has no DDS-Security), and it never runs unsecured "
                         "when security was asked for: run the rclpy node (ros2 run glpma_ros fk_node --ros-args "
                         "--enclave /glpma_fk, or ros2 launch glpma_ros fk.launch.py secure:=true keystore:=DIR), "
                         f"or unset {SECURITY_ENABLE_VAR}")
