"""Smooth test trajectories (true solver variables per step)."""
import numpy as np

from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector


def rpr_loop(x0, steps=1000):
    """A closed loop through the 3-RPR workspace around ``x0``."""
    t = 2 * np.pi * np.arange(steps) / steps
    return x0 + np.column_stack((20 * np.sin(t), 15 * np.sin(2 * t), 0.3 * np.sin(t)))


def hexapod_helix(model, x0, steps=1000, radius=30.0, rise=40.0, twist=0.2):
    """A helix of the platform origin with a rotation about z, starting at ``x0``."""
    pose = model.pose(x0)
    R0 = matrix_from_quaternion(pose.orientation)
    out = []
    for k in range(steps):
        t = 2 * np.pi * k / steps
        p = pose.position + np.array([radius * (np.cos(t) - 1), radius * np.sin(t), rise * t / (2 * np.pi)])
        R = rotation_from_vector(np.array([0.0, 0.0, twist * np.sin(t)])) @ R0
        out.append(model.variables_from_pose(p, quaternion_from_matrix(R)))
    return np.array(out)
