"""What the scripts in benchmarks/ share: frisicp_bench.script, datasets.default_data_dir, frisicp_bench.neighbours."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import frisicp_core.levels as levels
from frisicp_bench import script
from frisicp_bench.datasets import default_data_dir
from frisicp_bench.neighbours import counting_queries, neighbours_class
from frisicp_core import NearestNeighbors, bumpy_surface, register

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = str(ROOT / "benchmarks" / "example.py")


def test_the_data_folder_is_frisicp_data_when_set(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("FRISICP_DATA", str(tmp_path))
    assert default_data_dir() == tmp_path


def test_the_data_folder_is_beside_the_checkout_from_any_directory(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.delenv("FRISICP_DATA", raising=False)
    monkeypatch.chdir(tmp_path)
    assert default_data_dir() == ROOT.parent / "shared" / "data"


def test_a_report_goes_to_docs_and_a_quick_run_to_build() -> None:
    command = script.parser(SCRIPT, "Example.\n\nMore.", "one case", report=True, seed=True)
    full = script.parse(command, ["--seed", "3"])
    quick = script.parse(command, ["--quick"])
    assert (full.out, quick.out) == (ROOT / "docs" / "example.md", ROOT / "build" / "example.md")
    assert script.command_line(full) == "python benchmarks/example.py --seed 3"
    assert script.parse(command, ["--out", "x.md"]).out == Path("x.md")
    own = script.parser(SCRIPT, None, "one case")  # a script with its own --out rule keeps it
    own.add_argument("--out", type=Path, default=None)
    assert script.parse(own, ["--quick"]).out is None


def test_missing_data_is_a_skip_that_names_the_file(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from frisicp_bench.datasets import bunny_points

    args = script.parse(script.parser(SCRIPT, None, "one case", data=True), ["--data", str(tmp_path)])
    assert script.load_data(args, lambda data: bunny_points(data, "bun000.ply")) is None
    assert (
        f"example: skipped, no data: {tmp_path / 'bunny' / 'bun000.ply'} is missing"
        in capsys.readouterr().err
    )


def test_the_core_builds_its_trees_as_the_class_put_in_its_place_for_the_block() -> None:
    built: list[NearestNeighbors] = []

    class Recording(NearestNeighbors):
        def __init__(self, points: np.ndarray, backend: str = "auto") -> None:
            super().__init__(points, backend)
            built.append(self)

    data, model = 1.3 * bumpy_surface(300, seed=1), bumpy_surface(250, seed=0)
    plain = register(data, model)
    with neighbours_class(Recording):
        recorded = register(data, model)
    assert len(built) >= 2  # a data and a model tree at least
    assert levels.NearestNeighbors is NearestNeighbors  # restored
    np.testing.assert_array_equal(recorded.similarity.matrix(), plain.similarity.matrix())


def test_counting_queries_counts_query_points_and_resets_on_reading() -> None:
    data, model = 1.3 * bumpy_surface(300, seed=1), bumpy_surface(250, seed=0)
    with counting_queries() as queried:
        register(data, model)
        first = queried()
        assert queried() == 0
        NearestNeighbors(model).query(data[:10])  # built outside the core: not replaced, not counted
        assert queried() == 0
        levels.NearestNeighbors(model).query(data[:10])
        assert queried() == 10
    assert first >= data.shape[0] + model.shape[0]  # at least one full bidirectional pass
