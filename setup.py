"""ament_python package: `colcon build` installs it for `ros2 run`; `pip install .` for everyone else.

Python dependencies are declared here once; package.xml names the ROS/rosdep side.
"""

from glob import glob

from setuptools import setup

PACKAGE = "frisicp_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    # Layers, each importing only the ones below it: frisicp_ros.cli / .node -> .bag -> .stream ->
    # frisicp_core; frisicp_bench (the paper's experiments, `frisicp bench`) uses only frisicp_core.
    packages=[
        "frisicp_core",
        "frisicp_ros",
        "frisicp_ros.stream",
        "frisicp_ros.node",
        "frisicp_ros.bag",
        "frisicp_ros.cli",
        "frisicp_bench",
    ],
    package_data={name: ["py.typed"] for name in ("frisicp_core", "frisicp_ros", "frisicp_bench")},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml") + glob("config/*.rviz")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
    ],
    python_requires=">=3.10",
    # Lower bounds are tested: `make test-floors` installs exactly these and runs the bag tests.
    install_requires=[
        "numpy>=1.24",
        "scipy>=1.10",
        # Kept after measuring the alternatives (docs/nn_backends.md): ~1.7x scipy's cKDTree in
        # register; nanoflann bindings 0.99-1.26x of it, not worth a dependency. cKDTree is the fallback.
        "pykdtree>=1.3.6",  # the first with wheels (1.3.0 no longer builds)
        # register() runs OpenMP (pykdtree) and BLAS on one thread (frisicp_core.threads): their
        # default threads made it 3.5x slower on a busy 2-core machine. 3.0: ThreadpoolController.
        "threadpoolctl>=3.0",
        "plyfile>=1.0",  # PLY (ASCII and binary) reading for the CLI
        "pypcd4>=1.1",  # PCD (ascii, binary, binary_compressed) reading for the CLI
        # Offline bag mode, no ROS installation needed. 0.11: AnyReader opens bare .db3/.mcap files
        # (0.10.9 added the MCAP writer of the result bag). Only its public API is used.
        "rosbags>=0.11",
        # MCAP through its own maintainers' reader: every chunk's CRC checked (frisicp_ros.bag.mcap_bag).
        "mcap>=1.1",
        "tqdm>=4.60",  # progress bar of the bag mode
        "matplotlib>=3.6",  # pictures: frisicp register/bag --plot, frisicp-demo (imported only to draw)
    ],
    extras_require={
        "ros": [
            "ros-jazzy-rclpy[fastrtps]",
            "ros-jazzy-common-interfaces",
            "ros-jazzy-rcl-lifecycle",  # register_lifecycle_node (rclpy.lifecycle)
            "ros-jazzy-lifecycle-msgs",
        ],
        # `frisicp bag --scheduler`: a Dask cluster's scheduler, worker management and deployment
        # (dask-jobqueue, dask-kubernetes, the helm chart) instead of a home-made distributed pool.
        "dask": ["distributed>=2024.8"],
        "test": [
            "distributed>=2024.8",  # the cluster tests start a real scheduler and workers
            "pytest>=7",
            # `make test` runs the computing tests two at a time (a file per worker): CI's 30 minutes
            "pytest-xdist>=3.5",
            "mcap-ros2-support>=0.5",
            "colcon-common-extensions",
            "pillow>=9",
        ],
        "bench": ["matplotlib>=3.6", "pillow>=9", "threadpoolctl>=3"],
        # The other 1-NN libraries that benchmarks/nn_backends.py compares (it skips missing ones).
        # Never a runtime dependency: none was clearly faster than pykdtree (docs/nn_backends.md).
        "nn-bench": [
            "threadpoolctl>=3",
            "small-gicp>=1.0",
            "pynanoflann>=0.10",
            "napf>=0.1",
            "scikit-learn>=1.3",
            "faiss-cpu>=1.8",
            "kiss-icp>=1.0",
        ],
        # `make lint`; pinned, since new releases add rules and change formatting.
        "lint": ["ruff==0.17.6", "mypy==2.4.1"],
        # Only for comparing with Open3D in `frisicp bench` (about 900 MB; its wheel also needs
        # the system library libusb-1.0). Never a runtime or test dependency.
        "open3d": ["open3d>=0.18"],
    },
    zip_safe=True,
    maintainer="frisicp_ros maintainers",
    maintainer_email="maintainers@frisicp-ros.invalid",
    description="Scale-aware point cloud registration (FRISICP) for ROS 2",
    license="BSD-3-Clause",
    entry_points={
        "console_scripts": [
            "frisicp = frisicp_ros.cli.main:main",
            "register_node = frisicp_ros.node.node:main",
            "register_lifecycle_node = frisicp_ros.node.lifecycle:main",
            "frisicp-demo = frisicp_ros.node.demo:main",
        ],
    },
)
