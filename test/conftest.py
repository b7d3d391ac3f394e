import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from glpma_ros.config import load_manipulator

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"
RPR_YAML = CONFIG / "planar_3rpr_seed.yaml"
HEX_YAML = CONFIG / "hexapod_66_rolland.yaml"


@pytest.fixture(scope="session")
def rpr():
    return load_manipulator(RPR_YAML)


@pytest.fixture(scope="session")
def hexapod():
    return load_manipulator(HEX_YAML)


@pytest.fixture(scope="session")
def rpr_solutions():
    doc = yaml.safe_load(RPR_YAML.read_text())
    return [np.array([s["x"], s["y"], math.radians(s["theta_deg"])]) for s in doc["real_solutions"]]


@pytest.fixture(scope="session")
def hex_published():
    return np.array(yaml.safe_load(HEX_YAML.read_text())["published_solutions"])
