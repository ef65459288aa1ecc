"""ament_python package fsreg_ros (colcon build, or pip install for the core alone)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "fsreg_ros"

# One executable per node, as `ros2 run fsreg_ros <name>` expects, plus the tools.
NODES = {
    "parser": "fsreg_ros.nodes.parser:main",
    "reference_resolution": "fsreg_ros.nodes.reference_resolution:main",
    "consultant": "fsreg_ros.nodes.consultant:main",
    "wm_manager": "fsreg_ros.nodes.wm_manager:main",
    "reg": "fsreg_ros.nodes.reg:main",
    "dialogue_player": "fsreg_ros.nodes.dialogue_player:main",
}
TOOLS = {
    "fsreg-sim": "fsreg_ros.tools.sim:sim_main",
    "fsreg-graph": "fsreg_ros.tools.graph:main",
    "fsreg-up": "fsreg_ros.tools.up:main",
    "fsreg-ctl": "fsreg_ros.tools.ctl:main",
    "fsreg-eval": "fsreg_ros.research.cli:eval_main",
    "fsreg-sweep": "fsreg_ros.research.cli:sweep_main",
    "fsreg-plot": "fsreg_ros.research.cli:plot_main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    # ROS wheels are deliberately not listed: a real ROS install provides rclpy and
    # the message packages itself (requirements-ros.txt pins them for a venv).
    install_requires=["setuptools", "pyyaml>=6", "pydantic>=2.5", "numpy>=1.24", "rosbags>=0.11.9",
                      "ruamel.yaml.clib>=0.2.15; platform_python_implementation == 'CPython'", "snowballstemmer>=3.1"],
    # Dask for research jobs beyond one machine (fsreg-sweep --cluster/--scheduler): pip install fsreg_ros[cluster].
    # The same pin is in requirements-dev.txt, so the test suite always runs the cluster tests.
    extras_require={"cluster": ["dask[distributed]==2026.8.0"]},
    zip_safe=True,
    maintainer="fsreg developers",
    maintainer_email="fsreg@example.org",
    description="Forgetting-sensitive referring expression generation as a ROS 2 node graph",
    license="BSD-3-Clause",
    python_requires=">=3.10",
    entry_points={
        "console_scripts": [f"{name}={target}" for name, target in {**NODES, **TOOLS}.items()],
        # The public test harness's fixtures (fsreg_ros.testing), for any pytest run where fsreg is installed.
        "pytest11": ["fsreg = fsreg_ros.testing.plugin"],
    },
)
