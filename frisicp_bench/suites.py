"""Which families and scales a run covers: the full paper protocol, or the quick CI subset."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .cases import PAPER_SCALES, Family
from .families import (
    MAP_FILE,
    MAP_SCANS,
    SCAN_EVERY,
    SHAPE_CLASSES,
    bunny_self_family,
    paired_contour_family,
    scan_pair_family,
    scan_to_map_family,
    self_contour_family,
)

# The registration picture of the scan-in-map experiment shows its first family.
SCAN_TO_MAP_FIGURE = "registration_scan_to_map.png"


@dataclass(frozen=True)
class Suite:
    name: str
    scales: tuple[float, ...]
    builders: tuple[Callable[[Path], Family], ...]  # each loads one family from the data folder

    def families(self, data_dir: Path) -> list[Family]:
        return [build(data_dir) for build in self.builders]


def _contour_builders(shape_class: str) -> tuple[Callable[[Path], Family], ...]:
    return (lambda d: self_contour_family(d, shape_class), lambda d: paired_contour_family(d, shape_class))


def _scan_to_map_builder(scan: str, figure: str | None) -> Callable[[Path], Family]:
    return lambda d: scan_to_map_family(d, scan, MAP_FILE, SCAN_EVERY, figure)


def full_suite() -> Suite:
    """The paper's protocol: four 2-D classes (self and instance pairs), bunny and a scan pair, 15 scales;
    and ours: each of four real scans onto the bunny reconstruction (a scan in its map, thinned)."""
    builders = [b for shape_class in SHAPE_CLASSES for b in _contour_builders(shape_class)]
    builders += [bunny_self_family, scan_pair_family]
    builders += [
        _scan_to_map_builder(scan, SCAN_TO_MAP_FIGURE if k == 0 else None) for k, scan in enumerate(MAP_SCANS)
    ]
    return Suite("full", PAPER_SCALES, tuple(builders))


def quick_suite() -> Suite:
    """For CI (well under a minute): the apple pairs, the 8,171-point bunny and the full suite's first
    scan-in-map family, at 3 of the 15 scales."""
    return Suite(
        "quick",
        (0.1, 0.9, 2.9),
        (
            *_contour_builders("apple"),
            lambda d: bunny_self_family(d, "bun_zipper_res2.ply"),
            _scan_to_map_builder(MAP_SCANS[0], SCAN_TO_MAP_FIGURE),
        ),
    )
