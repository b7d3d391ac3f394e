"""solve-all finds exactly the real assembly modes of both benchmark manipulators."""
import numpy as np

from glpma_ros.modes.multistart import solve_all


def test_rpr_two_solutions(rpr, rpr_solutions):
    res = solve_all(rpr, rpr.example_leg_lengths, runs=50, seed=0)
    assert len(res.solutions) == 2
    for ref in rpr_solutions:
        match = [s for s in res.solutions if np.all(np.abs(s.x[:2] - ref[:2]) < 1e-6)]
        assert len(match) == 1
        assert abs(np.remainder(match[0].x[2] - ref[2] + np.pi, 2 * np.pi) - np.pi) < 1e-8
        assert np.max(np.abs(rpr.residuals(match[0].x, rpr.example_leg_lengths))) < 1e-9


def test_hexapod_sixteen_solutions_match_published(hexapod, hex_published):
    res = solve_all(hexapod, hexapod.example_leg_lengths, runs=200, seed=0)
    assert len(res.solutions) == 16
    used = set()
    for s in res.solutions:
        dev = np.max(np.abs(hex_published - s.x), axis=1)
        k = int(np.argmin(dev))
        assert dev[k] < 0.05, dev[k]
        used.add(k)
        assert s.fun < 1e-20
    assert len(used) == 16  # one-to-one: no spurious or duplicate solution
