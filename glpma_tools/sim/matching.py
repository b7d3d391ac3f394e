"""Pairing each pose with the input it answers: moved to :mod:`glpma_ros.testing.matching` (users'
launch tests use it too, and the node's package does not import the tools); the tools import it from
here as before."""
from glpma_ros.testing.matching import (  # noqa: F401
                                        LEGS_MATCH_REL,
                                        ORIENTATION_TOL_RAD,
                                        POSITION_TOL_M,
                                        Comparison,
                                        compare,
                                        legs_for,
                                        pair,
                                        quaternion_angle,
                                        split_at_stamp,
)
