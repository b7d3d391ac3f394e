"""The published figures the benchmark reproduces (mean over 100 runs).

Chandra & Rolland (2014), Table 5 (3-RPR: init U[-50, 50]^3, success = fitness < 1e-20 within 10,000 evaluations) and
Table 8 (6-6 hexapod: init U[-1000, 1000]^9, 500,000 evaluations).  Each entry: mean evaluations, their +/- column,
mean time (s), its +/- column, success rate (%).  The papers ran the pure evolutionary algorithms (no refinement).

Rolland & Chandra (2016), section 5.5.2: all 16 real solutions of the hexapod from 100 independent G3-PCX runs from
U[-2000, 2000]^9, under 35 s in total, 0.15-2.5 mm from the exact solutions.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Published:
    evals: float
    evals_pm: float
    time_s: float
    time_pm: float
    success: float


#: key: (solver, population, local population or None)
TABLE5 = {
    ("rcga", 50, None): Published(7301, 218, 0.056, 0.002, 100),
    ("rcga", 100, None): Published(5111, 189, 0.029, 0.001, 100),
    ("g3pcx", 100, None): Published(2984, 73, 0.012, 0.002, 90),
    ("glpma", 100, 100): Published(7448, 243, 0.059, 0.002, 100),
}

TABLE8 = {
    ("rcga", 200, None): Published(302_348, 1432, 3.928, 0.136, 100),
    ("g3pcx", 200, None): Published(80_306, 454, 0.267, 0.015, 90),
    ("g3pcx", 600, None): Published(77_393, 1713, 0.326, 0.013, 100),
    ("g3pcx", 1000, None): Published(100_682, 2343, 0.535, 0.017, 100),
    ("glpma", 200, 200): Published(192_998, 597, 1.9916, 0.123, 100),
}

PUBLISHED = {"planar_3rpr": TABLE5, "hexapod_66": TABLE8}
TABLE_NAME = {"planar_3rpr": "001 Table 5", "hexapod_66": "001 Table 8"}

#: 002 section 5.5.2
ALL_SOLUTIONS = {"count": 16, "runs": 100, "time_s": 35.0, "accuracy_mm": (0.15, 2.5), "init_range": (-2000, 2000)}

#: success (%) of pure G3-PCX on 001 Table 5's protocol in earlier runs of this project with faithful implementations
#: (pypop7, pymoo, and a minimal one written from Deb's description), for comparison
FAITHFUL_3RPR = {"pypop7": 10, "pymoo": 0, "minimal faithful": 10}
