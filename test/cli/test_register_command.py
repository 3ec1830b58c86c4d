"""`frisicp register DATA MODEL`: every supported file format, JSON output, clean errors."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from plyfile import PlyData, PlyElement
from pypcd4 import Encoding, PointCloud
from support.png import png_size
from support.scripts import installed_script

from frisicp_core import Similarity, bumpy_surface, rotation_angle
from frisicp_core.io import CloudFileError, read_points

FRISICP = installed_script("frisicp")
MODEL = bumpy_surface(2000, seed=3)
TRUTH = Similarity.from_quaternion(2.5, [0.1, 0.2, 0.3, 0.9], [0.5, -1.0, 2.0])
DATA = TRUTH.inverse().apply(MODEL)


def write_ply(path: Path, points: np.ndarray, text: bool) -> None:
    vertex = np.array([tuple(p) for p in points], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    PlyData([PlyElement.describe(vertex, "vertex")], text=text).write(str(path))


def write_pcd(path: Path, points: np.ndarray, encoding: Encoding) -> None:
    PointCloud.from_xyz_points(points.astype(np.float32)).save(path, encoding=encoding)


WRITERS = {
    "ascii.ply": lambda p, x: write_ply(p, x, text=True),
    "binary.ply": lambda p, x: write_ply(p, x, text=False),
    "ascii.pcd": lambda p, x: write_pcd(p, x, Encoding.ASCII),
    "binary.pcd": lambda p, x: write_pcd(p, x, Encoding.BINARY),
    "compressed.pcd": lambda p, x: write_pcd(p, x, Encoding.BINARY_COMPRESSED),
    "plain.xyz": lambda p, x: np.savetxt(p, x),
    "header.csv": lambda p, x: np.savetxt(p, x, delimiter=",", header="x,y,z", comments=""),
    "array.npy": lambda p, x: np.save(p, x),
}


@pytest.mark.parametrize("kind", WRITERS)
def test_every_format_reads_back_the_coordinates(tmp_path, kind):
    path = tmp_path / kind
    WRITERS[kind](path, MODEL)
    tolerance = 1e-6 if kind.endswith(".pcd") else 1e-12  # PCD stores float32
    np.testing.assert_allclose(read_points(path), MODEL, atol=tolerance * 10)


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([FRISICP, *args], capture_output=True, text=True, timeout=120)


def test_register_prints_json_with_the_documented_keys(tmp_path):
    WRITERS["binary.ply"](tmp_path / "data.ply", DATA)
    WRITERS["compressed.pcd"](tmp_path / "model.pcd", MODEL)
    done = run("register", str(tmp_path / "data.ply"), str(tmp_path / "model.pcd"), "--json")
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert {"scale", "rotation", "translation", "rms", "iterations", "converged", "seconds"} <= out.keys()
    assert out["scale"] == pytest.approx(2.5, rel=1e-5)
    assert np.rad2deg(rotation_angle(np.array(out["rotation"]).T @ TRUTH.rotation)) < 0.01
    np.testing.assert_allclose(out["translation"], TRUTH.translation, atol=1e-3)
    assert out["converged"] is True


def test_register_human_output_and_methods(tmp_path):
    np.save(tmp_path / "data.npy", DATA)
    np.save(tmp_path / "model.npy", MODEL)
    done = run("register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), "--method", "icp")
    assert "method       icp" in done.stdout and "scale        1" in done.stdout
    done = run("register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), "--paper")
    assert done.returncode == 0 and "quaternion" in done.stdout and "converged    True" in done.stdout


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "no such file"),
        (
            b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1\n",
            "cannot read it as PLY",
        ),
        (b"", "the file is empty"),
    ],
)
def test_bad_files_exit_2_with_one_line_and_no_traceback(tmp_path, content, message):
    path = tmp_path / "broken.ply"
    if content is not None:
        path.write_bytes(content)
    done = run("register", str(path), str(path))
    assert done.returncode == 2
    assert message in done.stderr and "Traceback" not in done.stderr


def test_directories_fifos_and_empty_files_are_named_for_what_they_are(tmp_path):
    """A FIFO or a directory was "no such file"; an empty .pcd printed pydantic's 19-line error."""
    os.mkfifo(tmp_path / "fifo.xyz")
    (tmp_path / "folder.ply").mkdir()
    (tmp_path / "empty.pcd").write_bytes(b"")
    (tmp_path / "junk.pcd").write_bytes(b"not a header\n")
    (tmp_path / "header_only.xyz").write_text("x y z\n")
    np.save(tmp_path / "complex.npy", MODEL * 1j)
    for name, message in (
        ("fifo.xyz", "not a regular file (a FIFO, socket or device)"),
        ("folder.ply", "is a directory, not a point cloud file"),
        ("empty.pcd", "the file is empty (0 bytes)"),
        ("junk.pcd", "cannot read it as PCD (the header is incomplete or invalid: fields, size,"),
        ("header_only.xyz", "no points (a header line and no rows)"),
        ("complex.npy", "holds complex numbers (complex128), not coordinates"),
    ):
        done = run("register", str(tmp_path / name), str(tmp_path / name))
        assert done.returncode == 2 and message in done.stderr, (name, done.stderr)
        assert done.stderr.count("\n") == 1, done.stderr


def test_data_in_large_units_registers(tmp_path):
    """The data in units 1e80 times the model's ended in `IndexError: index 4294967295` and exit 1."""
    np.save(tmp_path / "data.npy", DATA * 1e80)
    np.save(tmp_path / "model.npy", MODEL)
    done = run("register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), "--json")
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["reliable"] and out["scale"] == pytest.approx(2.5e-80, rel=1e-6)
    np.testing.assert_allclose(out["translation"], TRUTH.translation, atol=1e-5)


def test_a_closed_stdout_ends_quietly(tmp_path):
    """`frisicp register ... | head -1` printed a BrokenPipeError traceback."""
    np.save(tmp_path / "data.npy", DATA)
    np.save(tmp_path / "model.npy", MODEL)
    reader, writer = os.pipe()
    os.close(reader)  # nobody will read: the first write fails
    done = subprocess.run(
        [FRISICP, "register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy")],
        stdout=writer,
        stderr=subprocess.PIPE,
        text=True,
        timeout=120,
    )
    os.close(writer)
    assert done.returncode == 1 and done.stderr == ""


def test_nan_points_are_refused_unless_dropping_was_asked_for(tmp_path):
    data = DATA.copy()
    data[::100] = np.nan
    np.save(tmp_path / "data.npy", data)
    np.save(tmp_path / "model.npy", MODEL)
    done = run("register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"))
    assert done.returncode == 2 and "NaN or Inf" in done.stderr
    done = run(
        "register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), "--drop-nonfinite", "--json"
    )
    assert done.returncode == 0 and json.loads(done.stdout)["scale"] == pytest.approx(2.5, rel=1e-3)


def test_a_preset_and_an_option_that_disagree_are_refused_never_ignored(tmp_path):
    np.save(tmp_path / "data.npy", DATA)
    np.save(tmp_path / "model.npy", MODEL)
    files = (str(tmp_path / "data.npy"), str(tmp_path / "model.npy"))
    for extra, message in (
        (["--paper", "--overlap", "0.9"], "--overlap 0.9 conflicts with --paper, which sets overlap 1.0"),
        (["--paper", "--init", "moments"], "conflicts with --paper, which sets initialization identity"),
        (["--levels", "0"], "levels must be in [1, 10]"),
    ):
        done = run("register", *files, *extra)
        assert done.returncode == 2 and message in done.stderr, (extra, done.stderr)
        assert "Traceback" not in done.stderr
    # A value the preset agrees with, or an option it leaves alone, is fine.
    for extra in (["--paper", "--overlap", "1"], ["--paper", "--max-iterations", "200"]):
        done = run("register", *files, *extra, "--json")
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout)["scale"] == pytest.approx(2.5, rel=1e-3)


def test_unknown_extension(tmp_path):
    (tmp_path / "cloud.obj").write_text("v 1 2 3\n")
    with pytest.raises(CloudFileError, match="unknown extension"):
        read_points(tmp_path / "cloud.obj")


def test_numeric_options_are_bounded_like_the_node_parameters(capsys):
    """`--levels 100000000` ran out of memory with a traceback; every number has a range."""
    from frisicp_ros.cli import main as cli

    for flag, value, name in (
        ("--levels", "100000000", "levels"),
        ("--max-iterations", "10000000000", "max_iterations"),
        ("--coarsest-points", "10000000000", "coarsest_points"),
        ("--overlap", "nan", "overlap"),
        ("--max-distance", "inf", "max_distance"),
    ):
        code = cli.main(["register", "a.xyz", "b.xyz", flag, value])
        err = capsys.readouterr().err
        assert code == 2 and f"{name} must be in [" in err, err


def test_an_implausible_result_is_said_and_exits_1(tmp_path, capsys, monkeypatch):
    """Whatever ICP returns for a hopeless pair is not a pose: the verdict is printed with its
    reason and the exit code is 1 (the verdict's thresholds are the core's; faked here)."""
    import dataclasses

    from frisicp_core import register
    from frisicp_ros.cli import main as cli
    from frisicp_ros.cli import register as register_command

    def implausible(*args, **kwargs):
        result = register(*args, **kwargs)
        return dataclasses.replace(result, reliable=False, reason="scale 1.5e+40 is far from the size ratio")

    monkeypatch.setattr(register_command, "register", implausible)
    data = bumpy_surface(300, seed=1)
    np.save(tmp_path / "data.npy", data)
    np.save(tmp_path / "model.npy", data * 2.0)
    for json_flag in ([], ["--json"]):
        code = cli.main(["register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), *json_flag])
        out = capsys.readouterr().out
        assert code == 1
        if json_flag:
            assert json.loads(out)["reliable"] is False and "1.5e+40" in json.loads(out)["reason"]
        else:
            assert "reliable     False  (scale 1.5e+40 is far from the size ratio)" in out


def test_plot_draws_before_after_and_distances_into_a_png(tmp_path, capsys):
    from frisicp_ros.cli import main as cli

    np.save(tmp_path / "data.npy", DATA)
    np.save(tmp_path / "model.npy", MODEL)
    picture = tmp_path / "alignment.png"
    code = cli.main(
        ["register", str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), "--plot", str(picture)]
    )
    assert code == 0, capsys.readouterr().err
    width, height = png_size(picture)
    assert width > 2 * height > 500  # three views and the histogram, two rows
    assert picture.stat().st_size < 200_000


def test_initial_guess_finds_what_no_blind_search_can(tmp_path, capsys):
    """The symmetric scene of test_guess: blind never right and reliable, with --initial right."""
    from support.guess_scene import right_and_reliable, symmetric_scene_clouds

    from frisicp_ros.cli import main as cli
    from frisicp_ros.stream.outputs import rosbags_message_types
    from frisicp_ros.stream.pointcloud2 import cloud_to_points

    model, (data, *_), truth, rough = symmetric_scene_clouds(rosbags_message_types())
    np.save(tmp_path / "data.npy", cloud_to_points(data, 3))
    np.save(tmp_path / "model.npy", cloud_to_points(model, 3))
    files = [str(tmp_path / "data.npy"), str(tmp_path / "model.npy"), "--json"]

    def rotation_error(out: str) -> float:
        return np.degrees(rotation_angle(np.array(json.loads(out)["rotation"]).T @ truth.rotation))

    cli.main(["register", *files])
    out = capsys.readouterr().out
    assert not right_and_reliable(rotation_error(out), json.loads(out)["reliable"])
    pose = " ".join(str(v) for v in [*rough.translation, *rough.quaternion()])
    assert cli.main(["register", *files, "--initial", pose, "--initial-sigma", "5,0.1"]) == 0
    assert rotation_error(capsys.readouterr().out) < 0.5
    for extra, message in (
        (["--initial-sigma", "5,0.1"], "--initial-sigma applies only with --initial"),
        (["--initial", pose], "--initial needs --initial-sigma"),
        (["--initial", "1 2 3", "--initial-sigma", "5,0.1"], "7 or 8 numbers"),
    ):
        assert cli.main(["register", *files, *extra]) == 2
        assert message in capsys.readouterr().err
