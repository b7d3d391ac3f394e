"""``glpma-fk calibrate``: the real geometry (joints, leg offsets) from measured poses.

``glpma-fk calibrate CONFIG DATA --out NEW.yaml``: the manipulator's base joints, platform joints and
the zero offsets of the leg sensors, from leg readings paired with externally measured platform poses.

Modules: :mod:`.identify` (the theory: least squares on the inverse-kinematic leg residuals,
standard errors, identifiability), :mod:`.data` (the CSV and rosbag2 measurements),
:mod:`.yaml_edit` (NEW.yaml as CONFIG's text with the identified entries rewritten), :mod:`.cli` (the
command line, :func:`main`).  Simulated calibration data, for the tests, the benchmark and the README's
example, is a tool's: :mod:`glpma_tools.sim.calibration_data`.
"""
from .cli import main

__all__ = ["main"]
