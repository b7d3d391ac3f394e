"""Random starting poses of the multistart (:mod:`glpma_ros.modes.multistart_search`) over the region the
legs can reach: the platform centre uniform in the intersection of the balls around the legs' proximal points
``A_i`` of radius ``L_i + |b_i - c|`` (``c`` the centroid of the platform joints ``b_i``; any assembly has its
centre there, so an empty intersection proves there is none), by rejection from the intersection's bounding
box; the orientation uniform on SO(3) (a normalised 4-D Gaussian, i.e. a uniform unit quaternion; 3-RPR: an
angle uniform on (-pi, pi]).  The random numbers come from the caller's seeded ``numpy.random.Generator``, the
arithmetic is compiled.  Plain Python + NumPy/Numba: no ROS import."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..runtime import numba_cache

numba_cache.install()      # before the first compiled function (see numba_cache): this module may be imported first

#: rejection sampling of the reachable region: candidate rounds before falling back to its bounding box
REJECTION_ROUNDS = 20
#: rejection sampling: candidates drawn per round = still needed / acceptance so far x this margin (one
#: round usually suffices), at least MIN_CANDIDATES, the acceptance taken as at least MIN_ACCEPTANCE (a
#: region that small of its box costs more rounds, not more memory)
CANDIDATE_MARGIN = 1.25
MIN_CANDIDATES = 16
MIN_ACCEPTANCE = 1.0 / 64


@njit(cache=True, error_model="numpy")
def _in_every_ball(P, centres, radii):
    """Which rows of ``P`` lie in every ball (``centres[i]``, ``radii[i]``), compiled: the rejection
    test of the start sampler, run on every candidate."""
    inside = np.ones(P.shape[0], np.bool_)
    for k in range(P.shape[0]):
        for i in range(centres.shape[0]):
            d2 = 0.0
            for a in range(P.shape[1]):
                d2 += (P[k, a] - centres[i, a]) ** 2
            if d2 > radii[i] * radii[i]:
                inside[k] = False
                break
    return inside


class StartSampler:
    """Random starting poses (solver variables) over the region the legs can reach
    (module docstring).  ``empty``: the bounding box of that region is empty, which proves that
    no assembly exists."""

    def __init__(self, model, legs):
        self.model = model
        self.planar = model.platform.shape[1] == 2
        self.centroid = model.platform.mean(axis=0)
        radius = model.rods_of(legs) + np.linalg.norm(model.platform - self.centroid, axis=1)
        # the legs' proximal points: the base joints, or an actuated family's for these actuator positions
        centres = np.ascontiguousarray(model.proximal_points(legs), dtype=float)
        self.translation = model.n_pose == 3 and not self.planar     # deltas: the platform only translates
        self.centres, self.radii = centres, radius
        self.low = np.max(centres - radius[:, None], axis=0)
        self.high = np.min(centres + radius[:, None], axis=0)
        self.empty = bool(np.any(self.low > self.high))
        self.tried = self.accepted = 0
        self.acceptance = 1.0                # share of the box's candidates inside, as seen so far

    def _inside(self, P) -> np.ndarray:
        return _in_every_ball(P, self.centres, self.radii)

    def centres_in_reach(self, rng, m) -> np.ndarray:
        """``m`` platform centres uniform in the intersection of the balls: rejection from its
        bounding box, each round drawing as many candidates as the acceptance seen so far says are
        needed (times ``CANDIDATE_MARGIN``), so that one round usually suffices; after
        ``REJECTION_ROUNDS`` rounds the rest are taken from the box."""
        dim = self.low.size
        parts, have = [], 0
        for _ in range(REJECTION_ROUNDS):
            need = m - have
            n = max(MIN_CANDIDATES, math.ceil(need * CANDIDATE_MARGIN / max(self.acceptance, MIN_ACCEPTANCE)))
            P = rng.uniform(self.low, self.high, size=(n, dim))
            inside = P[self._inside(P)]
            self.tried += n
            self.accepted += len(inside)
            self.acceptance = self.accepted / self.tried
            parts.append(inside[:need])
            have += len(parts[-1])
            if have >= m:
                return np.concatenate(parts)
        parts.append(rng.uniform(self.low, self.high, size=(m - have, dim)))
        return np.concatenate(parts)

    def draw(self, rng, m) -> np.ndarray:
        """``m`` starts (rows of solver variables): centres in reach, orientations uniform (the
        random numbers from ``rng``, the arithmetic compiled)."""
        P = self.centres_in_reach(rng, m)
        if self.planar:
            return _planar_starts(P, rng.uniform(-math.pi, math.pi, size=m), self.centroid)
        if self.translation:
            return np.ascontiguousarray(P - self.centroid)
        return _spatial_starts(P, rng.standard_normal((m, 4)), self.model.frame - self.centroid)


@njit(cache=True, error_model="numpy")
def _planar_starts(P, theta, centroid):
    """3-RPR starts ``(x, y, theta)``: the platform's origin placed so that its joints' centroid,
    rotated by ``theta``, is at ``P``."""
    out = np.empty((P.shape[0], 3))
    cx, cy = centroid[0], centroid[1]
    for k in range(P.shape[0]):
        c, s = math.cos(theta[k]), math.sin(theta[k])
        out[k, 0] = P[k, 0] - (c * cx - s * cy)
        out[k, 1] = P[k, 1] - (s * cx + c * cy)
        out[k, 2] = theta[k]
    return out


@njit(cache=True, error_model="numpy")
def _spatial_starts(P, q, arms):
    """Hexapod starts ``(B1, B2, B3)``: ``B_k = P + R (b_k - c)`` with ``R`` the rotation of the
    normalised 4-D Gaussian ``q`` (a uniform unit quaternion ``x, y, z, w``) and ``arms`` the
    rows ``b_k - c``."""
    out = np.empty((P.shape[0], 3 * arms.shape[0]))
    R = np.empty((3, 3))
    for k in range(P.shape[0]):
        n = math.sqrt(q[k, 0] ** 2 + q[k, 1] ** 2 + q[k, 2] ** 2 + q[k, 3] ** 2)
        x, y, z, w = q[k, 0] / n, q[k, 1] / n, q[k, 2] / n, q[k, 3] / n
        R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
        R[1, 0], R[1, 1], R[1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
        R[2, 0], R[2, 1], R[2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        for j in range(arms.shape[0]):
            for a in range(3):
                out[k, 3 * j + a] = P[k, a] + R[a, 0] * arms[j, 0] + R[a, 1] * arms[j, 1] + R[a, 2] * arms[j, 2]
    return out
