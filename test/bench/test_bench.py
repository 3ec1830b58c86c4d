"""The paper benchmark (frisicp bench): contour extraction, cases, scoring, and the writers on tiny data."""

from __future__ import annotations

import json

import numpy as np
import pytest
from support.data import shared_file
from threadpoolctl import threadpool_limits

from frisicp_bench.cases import PAPER_SCALES, Family, make_cases
from frisicp_bench.contours import outer_contour
from frisicp_bench.families import scan_to_map_family
from frisicp_bench.methods import MethodSpec, core_method
from frisicp_bench.metrics import model_size, pose_errors, symmetric_rms
from frisicp_bench.reference import reference_placement
from frisicp_bench.runner import run_benchmark
from frisicp_bench.targets import check_targets
from frisicp_core import (
    Method,
    RegistrationConfig,
    Similarity,
    bumpy_surface,
    closed_contour,
    nearest,
    register,
)
from frisicp_ros.cli import main as cli


def test_paper_scales_are_the_15_of_the_paper() -> None:
    assert PAPER_SCALES == (0.1, 0.3, 0.5, 0.7, 0.9, 1.1, 1.3, 1.5, 1.7, 1.9, 2.1, 2.3, 2.5, 2.7, 2.9)


def test_outer_contour_keeps_only_the_outer_boundary_of_the_largest_component() -> None:
    image = np.zeros((40, 50), dtype=np.uint8)
    image[5:25, 10:30] = 1  # a 20 x 20 square ...
    image[10:15, 15:20] = 0  # ... with a hole, whose rim is not an outer boundary
    image[30:33, 40:43] = 1  # a smaller blob, dropped
    contour = outer_contour(image)
    assert contour.shape == (4 * 20 - 4, 2)
    xs, ys = contour[:, 0], 39 - contour[:, 1]  # back to image columns and rows
    assert xs.min() == 10 and xs.max() == 29 and ys.min() == 5 and ys.max() == 24
    on_square_rim = (xs == 10) | (xs == 29) | (ys == 5) | (ys == 24)
    assert on_square_rim.all()


def test_outer_contour_rejects_an_empty_image() -> None:
    with pytest.raises(ValueError, match="no foreground"):
        outer_contour(np.zeros((5, 5)))


def test_case_truth_undoes_the_seeded_perturbation_and_subsets_reproduce_cases() -> None:
    points = bumpy_surface(300)
    family = Family("surface", "3-D", "m", points, points, true_pose=True)
    full = make_cases(family, PAPER_SCALES, seed=3)
    subset = make_cases(family, (0.1, 2.9), seed=3)
    np.testing.assert_allclose(subset[1].data, full[-1].data)
    for case in full:
        np.testing.assert_allclose(case.truth.apply(case.data), points, atol=1e-9)
        assert case.truth.scale == pytest.approx(1.0 / case.scale)
    other_seed = make_cases(family, (0.1,), seed=4)[0]
    assert not np.allclose(other_seed.data, full[0].data)


def test_pose_errors_measure_each_component() -> None:
    points = closed_contour(100)
    truth = Similarity(2.0, np.eye(2), np.zeros(2))
    angle = np.radians(0.5)
    turned = Similarity(2.02, [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]], np.zeros(2))
    errors = pose_errors(turned, truth, points, size=10.0)
    assert errors.rotation_deg == pytest.approx(0.5)
    assert errors.scale == pytest.approx(0.01)
    assert not errors.success  # 1 % scale error is not below 1 %
    shifted = Similarity(2.0, np.eye(2), [0.04, 0.0])
    assert pose_errors(shifted, truth, points, size=10.0).translation == pytest.approx(0.004)
    assert pose_errors(shifted, truth, points, size=10.0).success


def test_symmetric_rms_sees_data_shrunk_onto_part_of_the_model() -> None:
    model = closed_contour(400)
    shrunk = 0.01 * model + model[0]
    assert symmetric_rms(model, model) == 0.0
    forward_only = np.sqrt(np.min(((shrunk[:, None] - model[None]) ** 2).sum(-1), axis=1).mean())
    assert symmetric_rms(shrunk, model) > 10 * forward_only


def test_reference_placement_fits_a_deformed_copy_better_than_its_starts() -> None:
    model = closed_contour(150)
    angle = np.linspace(0.0, 2 * np.pi, 150, endpoint=False)
    deformed = model * (1.0 + 0.03 * np.sin(7 * angle))[:, None]
    placement, rms = reference_placement(deformed, model, angles=4)
    assert 0.0 < rms < symmetric_rms(deformed, model)
    assert np.degrees(placement.rotation_angle()) < 2.0
    assert placement.scale == pytest.approx(1.0, abs=0.03)


def test_tiny_run_writes_tables_json_and_figures(tmp_path) -> None:
    from frisicp_bench.figures import write_figures
    from frisicp_bench.tables import write_tables

    contour = closed_contour(120)
    surface = bumpy_surface(300)
    angle = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    deformed = contour * (1.0 + 0.03 * np.sin(7 * angle))[:, None]
    placement, reference_rms = reference_placement(deformed, contour, angles=4)
    families = [
        Family("contour 1→1", "2-D", "u", contour, contour, true_pose=True),
        Family(
            "contour 2→1",
            "2-D",
            "u",
            placement.apply(deformed),
            contour,
            true_pose=False,
            reference_rms=reference_rms,
        ),
        Family("surface", "3-D", "u", surface, surface, true_pose=True),
    ]
    methods = [
        MethodSpec("frisicp", "FRISICP", core_method(RegistrationConfig.paper(Method.FRISICP))),
        MethodSpec("scale-icp", "Zinßer", core_method(RegistrationConfig.paper(Method.SCALE_ICP))),
    ]
    run = run_benchmark(families, methods, (0.3, 1.5), seed=0)
    assert len(run.records) == 3 * 2 * 2
    frisicp_true = [r for r in run.records if r.method == "frisicp" and r.family != "contour 2→1"]
    assert all(r.success for r in frisicp_true), [(r.family, r.scale, r.rotation_deg) for r in frisicp_true]
    assert all(r.rms_ratio is not None for r in run.records if r.family == "contour 2→1" and r.estimate)

    checks = check_targets(run)
    assert checks[0].met and "FRISICP" in checks[0].target
    figures = write_figures(run, tmp_path)
    written = write_tables(run, checks, {"machine": "test"}, [p.name for p in figures], tmp_path, "pytest")
    report = written[0].read_text()
    assert "Like the paper's Table 1" in report and "Like the paper's Table 2" in report
    assert "| contour 2→1 | mean over 2 |" in report
    document = json.loads(written[1].read_text())
    assert len(document["records"]) == 12 and document["targets"][0]["met"] is True
    assert {p.name for p in figures} >= {"convergence_2d.png", "registration_3d.png", "success_by_scale.png"}
    for path in figures:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000


def test_bench_command_names_the_missing_data_folder(tmp_path, capsys) -> None:
    code = cli.main(["bench", "--quick", "--data", str(tmp_path / "nowhere"), "--out", str(tmp_path / "out")])
    assert code == 2
    assert "nowhere" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.real_data
def test_apple_contour_from_the_real_silhouette() -> None:
    from frisicp_bench.datasets import silhouette_contour

    path = shared_file("mpeg7/apple-1.gif")
    contour = silhouette_contour(path.parents[1], "apple", 1)
    # A closed outline of a ~200 px wide apple: hundreds of boundary pixels, all on the image.
    assert 400 < contour.shape[0] < 1200
    assert contour.min() >= 0 and contour.max() < 256


def _write_ply(path, points_mm: np.ndarray) -> None:
    """An ASCII PLY in metres, like the Stanford files."""
    header = f"ply\nformat ascii 1.0\nelement vertex {len(points_mm)}\n"
    header += "".join(f"property double {axis}\n" for axis in "xyz") + "end_header\n"
    with path.open("w") as file:
        file.write(header)
        np.savetxt(file, points_mm / 1000.0, fmt="%.17g")


# A scan's pose in the common frame, as a bun.conf line states it (p -> R(q)^T p + t, metres).
_SCAN_POSE = "0.01 -0.02 0.005 0.0 0.38268343 0.0 0.92387953"  # 45 deg about y


def _tiny_data_folder(root) -> tuple[np.ndarray, np.ndarray]:
    """../shared/data in miniature: two apple silhouettes, a 1,500-point 'reconstruction' (mm)
    and the scan bun090, the third of it with x > 20 mm, stored in its own frame."""
    from PIL import Image

    (root / "mpeg7").mkdir(parents=True)
    rows, cols = np.mgrid[:48, :64]
    for instance, squash in ((1, 1.0), (2, 1.15)):
        blob = ((cols - 30) / 22.0) ** 2 + ((rows - 24) * squash / 15.0) ** 2 + 0.2 * (cols > 40) < 1.0
        Image.fromarray((255 * blob).astype(np.uint8)).save(root / "mpeg7" / f"apple-{instance}.gif")
    bunny = root / "bunny"
    bunny.mkdir()
    reconstruction = 60.0 * bumpy_surface(1500)
    _write_ply(bunny / "bun_zipper_res2.ply", reconstruction)
    seen = reconstruction[reconstruction[:, 0] > 20.0]
    (bunny / "bun.conf").write_text(f"camera 0 0 0 0 0 0 1\nbmesh bun090.ply {_SCAN_POSE}\n")
    pose = Similarity.from_quaternion(1.0, np.array(_SCAN_POSE.split()[3:], dtype=float), np.zeros(3))
    placement = Similarity(1.0, pose.rotation.T, 1000.0 * np.array(_SCAN_POSE.split()[:3], dtype=float))
    _write_ply(bunny / "bun090.ply", placement.inverse().apply(seen))
    return reconstruction, seen


def test_a_scan_in_its_map_is_placed_by_bun_conf_and_named_by_its_thinning(tmp_path) -> None:
    reconstruction, seen = _tiny_data_folder(tmp_path)
    family = scan_to_map_family(tmp_path, "bun090.ply", "bun_zipper_res2.ply", every=4, figure="picture.png")
    assert family.name == "bun090/4→zipper_res2" and family.true_pose and family.figure == "picture.png"
    np.testing.assert_allclose(family.model, reconstruction, atol=1e-9)
    # Every 4th scan point, each back on the map where the scan saw it.
    np.testing.assert_allclose(family.data, seen[::4], atol=1e-6)
    distance_sq, _ = nearest(family.model, family.data)
    assert distance_sq.max() < 1e-10
    assert 0.2 < len(seen) / len(reconstruction) < 0.5  # a scan sees part of its map


def test_each_partial_overlap_family_gets_its_own_registration_picture(tmp_path) -> None:
    from frisicp_bench.figures import write_figures

    surface = bumpy_surface(300)
    families = [
        Family("surface", "3-D", "u", surface, surface, true_pose=True),
        Family(
            "half→surface", "3-D", "u", surface[surface[:, 0] > 0], surface, true_pose=True, figure="a.png"
        ),
        Family(
            "third→surface", "3-D", "u", surface[surface[:, 0] > 0.5], surface, true_pose=True, figure="b.png"
        ),
    ]
    methods = [MethodSpec("frisicp-default", "FRISICP+", core_method(RegistrationConfig()))]
    run = run_benchmark(families, methods, (0.9,), seed=0)
    names = {path.name for path in write_figures(run, tmp_path)}
    assert names == {"convergence_3d.png", "registration_3d.png", "a.png", "b.png", "success_by_scale.png"}


def test_quick_bench_registers_a_scan_in_its_map_beside_the_other_families(tmp_path, capsys) -> None:
    _tiny_data_folder(tmp_path / "data")
    out = tmp_path / "out"
    args = [
        "bench",
        "--quick",
        "--data",
        str(tmp_path / "data"),
        "--out",
        str(out),
        "--no-open3d",
        "--no-figures",
    ]
    with threadpool_limits(1):  # as `make bench-paper-quick` runs it: OpenMP threads only slow tiny queries
        assert cli.main(args) == 0
    document = json.loads((out / "results.json").read_text())
    assert [f["name"] for f in document["families"]] == [
        "apple 1→1",
        "apple 2→1",
        "bunny (bun_zipper_res2)",
        "bun090/4→zipper_res2",
    ]
    scan_records = [r for r in document["records"] if r["family"] == "bun090/4→zipper_res2"]
    assert {r["method"] for r in scan_records} == {
        "frisicp",
        "frisicp-default",
        "icp",
        "scale-icp",
        "bounded-icp",
    }
    assert {r["scale"] for r in scan_records} == {0.1, 0.9, 2.9}
    report = (out / "README.md").read_text().splitlines()
    success_table = report[report.index("## Success rate per family") :]
    row = next(line for line in success_table if line.startswith("| bun090/4→zipper_res2 |"))
    assert row.count("%") == 5  # one success rate per method, side by side


@pytest.mark.real_data
@pytest.mark.parametrize("seed", range(6))
def test_a_scan_turned_up_to_30_degrees_in_its_map_registers_whatever_the_thinning(seed: int) -> None:
    """frisicp bench's hardest scan-to-map case (bun270/4 onto zipper_res2 at s = 0.5; the bench
    turns the scan up to 30 degrees). With the data only left in place at R = I, two of these six
    random thinnings settled 14-25 degrees off: the turned in-place hypotheses bring it into reach."""
    from frisicp_bench.families import MAP_FILE, SCAN_EVERY

    data_dir = shared_file("bunny/bun270.ply").parents[1]
    family = scan_to_map_family(data_dir, "bun270.ply", MAP_FILE, SCAN_EVERY)
    (case,) = make_cases(family, (0.5,), seed=0)
    result = register(case.data, family.model, RegistrationConfig(seed=seed))
    errors = pose_errors(result.similarity, case.truth, case.data, model_size(family.model))
    assert errors.success, errors
