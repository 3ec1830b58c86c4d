"""The compared registration methods behind one signature: ``run(data, model) -> Outcome``.

All of frisicp_core's methods run with the paper's settings (identity start, no trimming,
baselines single-level); FRISICP also runs with the package defaults (``RegistrationConfig()``:
overlap estimated per direction, hypothesis search). Open3D's point-to-point ICP with scale estimation is added when ``open3d`` imports.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from frisicp_core import FloatArray, Method, RegistrationConfig, Similarity, register

# Iteration cap of every method (frisicp_core's default); Open3D is given the same.
MAX_ITERATIONS = 100


@dataclass(frozen=True)
class ConvergencePoint:
    """One iteration of a run: the method's own error then, for convergence curves."""

    iteration: int  # counted over all levels
    level: int
    seconds: float
    rms: float  # forward RMS: data -> model nearest distances, on the level's points


@dataclass(frozen=True)
class Outcome:
    similarity: Similarity | None  # None when the method failed outright (``failure`` says why)
    iterations: int
    seconds: float
    converged: bool
    history: tuple[ConvergencePoint, ...] = ()
    failure: str | None = None


@dataclass(frozen=True)
class MethodSpec:
    key: str  # for JSON and file names
    label: str  # for tables and plots
    run: Callable[[FloatArray, FloatArray], Outcome]
    dims: tuple[int, ...] = (2, 3)


def core_method(config: RegistrationConfig) -> Callable[[FloatArray, FloatArray], Outcome]:
    def run(data: FloatArray, model: FloatArray) -> Outcome:
        result = register(data, model, config)
        history = tuple(
            ConvergencePoint(k, r.level, r.seconds, r.forward_rms)
            for k, r in enumerate(result.history, start=1)
        )
        return Outcome(result.similarity, sum(result.iterations), result.seconds, result.converged, history)

    return run


def open3d_transformation(
    data: FloatArray, model: FloatArray, start: Similarity | None = None, max_iterations: int = MAX_ITERATIONS
) -> FloatArray:
    """Open3D's point-to-point ICP with ``with_scaling=True``: the 4x4 matrix it returns.

    The correspondence distance limit is the model's bounding-box diagonal, so every pair counts
    (plain ICP, as in frisicp_core's baselines); ``start`` None is the identity, as in the paper.
    """
    import open3d as o3d

    reg = o3d.pipelines.registration
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(data))
    target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(model))
    reach = float(np.linalg.norm(model.max(axis=0) - model.min(axis=0)))
    result = reg.registration_icp(
        source,
        target,
        reach,
        np.eye(4) if start is None else start.matrix(),
        reg.TransformationEstimationPointToPoint(with_scaling=True),
        reg.ICPConvergenceCriteria(max_iteration=max_iterations),
    )
    return np.asarray(result.transformation)


def open3d_scaled_icp(data: FloatArray, model: FloatArray) -> Outcome:
    """:func:`open3d_transformation` from the identity, like the paper's baselines. Time includes
    building Open3D's clouds."""
    start = time.perf_counter()
    transformation = open3d_transformation(data, model)
    seconds = time.perf_counter() - start
    try:
        similarity = Similarity.from_matrix(transformation)
    except ValueError as err:  # a collapsed scale gives a singular matrix
        return Outcome(None, MAX_ITERATIONS, seconds, False, failure=f"open3d: {err}")
    # Open3D reports no iteration count; the cap is an upper bound, so it is not claimed.
    return Outcome(similarity, -1, seconds, True)


def open3d_available() -> bool:
    try:
        import open3d  # noqa: F401
    except (ImportError, OSError):  # OSError: a missing system library (libusb-1.0) of the wheel
        return False
    return True


def paper_methods() -> list[MethodSpec]:
    """The methods of the benchmark, FRISICP first; Open3D only when it imports."""
    methods = [
        MethodSpec("frisicp", "FRISICP", core_method(RegistrationConfig.paper(Method.FRISICP))),
        MethodSpec("frisicp-default", "FRISICP+", core_method(RegistrationConfig())),
        MethodSpec("icp", "ICP", core_method(RegistrationConfig.paper(Method.ICP))),
        MethodSpec("scale-icp", "Zinßer", core_method(RegistrationConfig.paper(Method.SCALE_ICP))),
        MethodSpec("bounded-icp", "Du", core_method(RegistrationConfig.paper(Method.BOUNDED_ICP))),
    ]
    if open3d_available():
        methods.append(MethodSpec("open3d", "Open3D", open3d_scaled_icp, dims=(3,)))
    return methods
