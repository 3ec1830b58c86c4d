"""The case families of the paper's protocol, built from the real data."""

from __future__ import annotations

from pathlib import Path

from .cases import Family
from .datasets import bunny_points, scan_pose, silhouette_contour
from .reference import START_ANGLES, reference_placement

# The paper's 2-D classes (its "Cock" is MPEG-7's chicken).
SHAPE_CLASSES = ("apple", "chicken", "deer", "horse")


def self_contour_family(data_dir: Path, shape_class: str) -> Family:
    """Instance 1 against itself: the true pose is known."""
    contour = silhouette_contour(data_dir, shape_class, 1)
    return Family(f"{shape_class} 1→1", "2-D", "px", contour, contour, true_pose=True)


def paired_contour_family(data_dir: Path, shape_class: str, angles: int = START_ANGLES) -> Family:
    """Instance 2 (data) against instance 1 (model), as in the paper: placed by the reference."""
    model = silhouette_contour(data_dir, shape_class, 1)
    data = silhouette_contour(data_dir, shape_class, 2)
    placement, rms = reference_placement(data, model, angles)
    return Family(
        f"{shape_class} 2→1", "2-D", "px", placement.apply(data), model, true_pose=False, reference_rms=rms
    )


def bunny_self_family(data_dir: Path, file_name: str = "bun_zipper.ply") -> Family:
    """The reconstruction against a scaled copy of itself (the paper's 3-D protocol)."""
    points = bunny_points(data_dir, file_name)
    label = "bunny" if file_name == "bun_zipper.ply" else f"bunny ({file_name.removesuffix('.ply')})"
    return Family(label, "3-D", "mm", points, points, true_pose=True)


def scan_pair_family(data_dir: Path, data_scan: str = "bun045.ply", model_scan: str = "bun000.ply") -> Family:
    """Two real scans placed by bun.conf's ground truth: partial overlap, true pose known."""
    model_pose = scan_pose(data_dir, model_scan)
    data_pose = scan_pose(data_dir, data_scan)
    placed = (model_pose.inverse() @ data_pose).apply(bunny_points(data_dir, data_scan))
    name = f"{data_scan.removesuffix('.ply')}→{model_scan.removesuffix('.ply')}"
    return Family(name, "3-D", "mm", placed, bunny_points(data_dir, model_scan), true_pose=True)
