"""`make bench-smoke` (tools/bench_smoke.py): every script once with --quick, two at a time, every
failure named with its output."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "tools" / "bench_smoke.py"


def smoke(folder: Path, logs: Path, jobs: int = 2) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(RUNNER), "--jobs", str(jobs), "--scripts", str(folder), "--logs", str(logs)],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_every_script_runs_with_quick_and_a_failure_is_named_with_its_output(tmp_path: Path) -> None:
    folder = tmp_path / "benchmarks"
    folder.mkdir()
    (folder / "fine.py").write_text(
        "import sys\nprint('fine', sys.argv[1:])\nprint('one part skipped: no ROS')\n"
    )
    (folder / "broken.py").write_text("print('half way')\nraise SystemExit(3)\n")
    (folder / "quiet.py").write_text("pass\n")
    result = smoke(folder, tmp_path / "logs")
    assert result.returncode == 1
    lines = result.stdout.splitlines()
    assert any(line.startswith("ok   fine (") for line in lines)
    assert "one part skipped: no ROS" in lines  # a script's skips are shown
    assert any(line.startswith("ok   quiet (") for line in lines)
    assert "half way" in lines  # the failing script's whole output, then its name
    assert any(line.startswith("FAIL broken (exit 3") for line in lines)
    assert lines[-1] == "bench-smoke FAILED: broken"
    assert (tmp_path / "logs" / "fine.log").read_text().startswith("fine ['--quick']")


def test_all_passing_exits_0_one_at_a_time_too(tmp_path: Path) -> None:
    folder = tmp_path / "benchmarks"
    folder.mkdir()
    for name in ("a", "b"):
        (folder / f"{name}.py").write_text("print('ok')\n")
    result = smoke(folder, tmp_path / "logs", jobs=1)
    assert result.returncode == 0, result.stdout
    assert "bench-smoke: 2 scripts, 1 at a time" in result.stdout
    assert smoke(folder, tmp_path / "logs", jobs=0).returncode == 2  # refused, said by argparse
