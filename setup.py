"""ament_python package jetpipe_ros (also installable with pip)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "jetpipe_ros"

setup(
    name=PACKAGE,
    version="0.2.0",
    packages=find_packages(exclude=["test", "test.*", "docs", "docs.*"]),
    package_data={"jetpipe_ros.diagnosis": ["diagnosis.schema.json"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/msg_defs", glob("msg_defs/*.yaml")),
    ],
    # rclpy and the ROS messages come from the ROS install or requirements-ros.txt.
    install_requires=["numpy", "scipy", "numba", "pyyaml", "matplotlib", "rosbags",
                      "threadpoolctl", "scikit-learn", "dask", "distributed",
                      "statsmodels"],
    python_requires=">=3.10",
    zip_safe=True,
    maintainer="jetpipe_ros developers",
    maintainer_email="jetpipe_ros@example.invalid",
    description="ROS 2 emulation of a jet-pipe electro-pneumatic servo actuator and sim-to-real "
                "tools",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "actuator_sim = jetpipe_ros.nodes.actuator_sim:main",
            "controller = jetpipe_ros.nodes.controller:main",
            "id_recorder = jetpipe_ros.nodes.id_recorder:main",
            "composed_campaign = jetpipe_ros.nodes.composed_campaign:main",
            "gap_monitor = jetpipe_ros.nodes.gap_monitor:main",
            "jetpipe = jetpipe_ros.cli:main",
        ],
    },
)
