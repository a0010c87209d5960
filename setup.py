"""The Python distribution of rollability_ros: sources, console script, dependencies and optional extras.

Two routes install the same sources (see README.md): ``scripts/setup.sh`` builds the interfaces with CMake into
a venv and then pip-installs this distribution on top; ``colcon build`` on a ROS 2 Jazzy install uses
CMakeLists.txt alone (package.xml says ament_cmake) and never runs this file.
"""
import glob

from setuptools import find_packages, setup

EXTRAS = {
    # physics, geometry and optimization: the design side
    "sim": ["pybullet==3.2.7", "cma>=4.0", "trimesh>=4.0", "scipy>=1.10", "networkx>=3.0", "lxml>=4.9", "xacro>=2.0",
            "ribs>=0.12,<0.13"],
    # learning the twin's likelihood once per robot and design set (rollability calibrate --prepare): its
    # networks are trained with scikit-learn (9 MB; sbi's would need torch, about 3 GB of wheels with CUDA)
    "calibration": ["scikit-learn>=1.3"],
    # the MuJoCo trial engine (sim.engine: mujoco)
    "mujoco": ["mujoco>=3.2"],
    # hand trial batches to a Ray cluster
    "cluster": ["ray>=2.9"],
    # figures of the report
    "report": ["matplotlib>=3.7"],
    # rig hardware: serial relay board, GPIO valve and light gates
    "hardware": ["pyserial>=3.5", "gpiod>=2.1"],
    # live progress line of study / bringup on a terminal (plain lines without it)
    "progress": ["rich>=12"],
    # live Foxglove view without a ROS install
    "view": ["foxglove-sdk>=0.10"],
    # mypy pinned: a newer release may report new errors (test/core/test_mypy.py runs it over mypy.ini)
    "test": ["pytest>=7", "pytest-timeout>=2", "pytest-rerunfailures>=14", "pytest-xdist>=3.5",
             "colcon-common-extensions>=0.3",
             "mypy==2.4.1", "types-PyYAML>=6.0"],
}
EXTRAS["all"] = sorted({req for name, reqs in EXTRAS.items() if name != "test" for req in reqs})

setup(
    name="rollability_ros",
    version="0.1.0",
    description="Design and validate passive self-righting profiles for small wheeled robots (ROS 2 Jazzy)",
    license="Apache-2.0",
    python_requires=">=3.10",
    packages=find_packages(include=["rollability_ros", "rollability_ros.*"]),
    # The rig side needs only these: it runs on a robot computer without the simulation extras.
    # lazy_loader: the core's faces (core/*/__init__.pyi, scientific-python SPEC 1) load a module when a name is used.
    install_requires=["lazy_loader>=0.4", "numpy>=1.23", "pyyaml>=6", "mcap>=1.1", "mcap-ros2-support>=0.5", "rosbags>=0.10", "zstandard"],
    extras_require=EXTRAS,
    # the faces' stubs: lazy_loader reads them at run time, type checkers too
    package_data={"rollability_ros.core": ["*/__init__.pyi"]},
    data_files=[
        ("share/rollability_ros/config", sorted(glob.glob("config/*.yaml") + glob.glob("config/*.json"))),
        ("share/rollability_ros/launch", sorted(glob.glob("launch/*.py"))),
    ],
    entry_points={"console_scripts": ["rollability = rollability_ros.cli:main"]},
)
