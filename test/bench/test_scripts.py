"""What the scripts in benchmarks/ share: frisicp_bench.script, datasets.default_data_dir, frisicp_bench.neighbours."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import frisicp_core.levels as levels  # the core module that builds the levels' trees
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


def test_trustworthy_fresh_draws_salt_every_seed_and_draw_0_is_the_committed_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """benchmarks/trustworthy.py --draw N builds other cases from the same recipes; without it
    the cases (and so docs/trustworthy.md) are the ones every earlier run built."""
    import os
    import zlib

    # The script sets OMP_NUM_THREADS when imported: undone after the test.
    monkeypatch.setenv("OMP_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import trustworthy

    committed = trustworthy.specs(quick=False)
    fresh = trustworthy.specs(quick=False, draw=1)
    assert len(committed) == len(fresh) == 224
    first = committed[0]
    assert first.seed == zlib.crc32(b"crop onto scene/rs1.pcd/0/10000")
    assert all(a.seed != b.seed for a, b in zip(committed, fresh, strict=True))
    assert len({spec.seed for spec in fresh}) == len(fresh)
    others = trustworthy.specs(False, 2, ("chef.pcd",), ())
    assert {spec.scene for spec in others if spec.suite == "frames"} == {"chef.pcd"}
    assert not [spec for spec in others if spec.cap == 0]
    with pytest.raises(SystemExit) as refused:  # no scene at all is a usage error, not a traceback
        trustworthy.main(["--scenes", " , ", "--quick"])
    assert refused.value.code == 2
