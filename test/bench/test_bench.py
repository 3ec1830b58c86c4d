"""The paper benchmark (frisicp bench): contour extraction, cases, scoring, and the writers on tiny data."""

from __future__ import annotations

import json

import numpy as np
import pytest
from support.data import shared_file

from frisicp_bench.cases import PAPER_SCALES, Family, make_cases
from frisicp_bench.contours import outer_contour
from frisicp_bench.methods import MethodSpec, core_method
from frisicp_bench.metrics import pose_errors, symmetric_rms
from frisicp_bench.reference import reference_placement
from frisicp_bench.runner import run_benchmark
from frisicp_bench.targets import check_targets
from frisicp_core import Method, RegistrationConfig, Similarity, bumpy_surface, closed_contour
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
