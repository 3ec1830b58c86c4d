"""What the scripts in benchmarks/ share (frisicp_bench.script, datasets.default_data_dir)."""

from __future__ import annotations

from pathlib import Path

import pytest

from frisicp_bench import script
from frisicp_bench.datasets import default_data_dir

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
