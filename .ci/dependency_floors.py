"""Print setup.py's runtime requirements pinned to their declared lower bounds (``pkg>=X`` ->
``pkg==X``), one argument each, for ``make test-floors``. A requirement without a lower bound
is an error: an undeclared floor cannot be tested."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

SETUP = Path(__file__).resolve().parents[1] / "setup.py"


def install_requires() -> list[str]:
    for node in ast.walk(ast.parse(SETUP.read_text())):
        if isinstance(node, ast.keyword) and node.arg == "install_requires":
            return list(ast.literal_eval(node.value))
    raise SystemExit(f"{SETUP}: no install_requires")


def main() -> None:
    pins = []
    for requirement in install_requires():
        name, bound, version = requirement.partition(">=")
        if not bound or "," in version:
            raise SystemExit(f"{requirement}: declare a plain lower bound (name>=version)")
        pins.append(f"{name.strip()}=={version.strip()}")
    print(" ".join(pins))


if __name__ == "__main__":
    sys.exit(main())
