"""Every trust report at once: successes, wrong-and-reliable results, calibration and the search's misses.

    python benchmarks/trust_summary.py            # docs/trustworthy*.json -> docs/trust_summary.md
    python benchmarks/trust_summary.py --quick    # the committed development report alone -> build/

Reads the JSON reports of ``benchmarks/trustworthy.py`` (each written by the command stored in
it) and registers nothing. One row per report: its cases, the results right, the successes
(right and reliable), the wrong-and-reliable results (the failure the package must never emit),
the right answers refused, the search's misses (refused although the start at the truth is right
and reliable: the data determine the pose there) and the reliable results within three of their
own sigmas per component (rotation / scale / translation). Then, per suite over the development
draws and over the held-out ones, how often the search succeeds where the data determine the
pose (``trustworthy.determined``): where the issue's success targets apply. Then every reliable
result whose error lies beyond three of its sigmas, and per scene of the scene suites the cases,
the results right, the successes and the cases the data determine.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from typing import Any

from trustworthy import (
    DEVELOPMENT_REPORTS,
    HELD_OUT_REPORTS,
    REPORTS_DIR,
    determined,
    pose_determined,
    search_misses,
    sigma_ratios,
)

from frisicp_bench import script
from frisicp_bench.report import markdown_table, write_report

TITLE = "Every trust report: successes, wrong and reliable, calibration, misses"
COMPONENTS = ("rotation", "scale", "translation")
SCENE_SUITES = ("crop onto scene", "scene onto crop", "sparse map onto scene", "frames", "jump")


def clouds(command: str) -> str:
    """The draw and the scenes a report's command ran (the development scenes by default)."""
    words = shlex.split(command)

    def option(name: str, default: str) -> str:
        return words[words.index(name) + 1] if name in words else default

    scenes = option("--scenes", "development scenes").replace(",", ", ")
    full = option("--full-resolution", "rs1.pcd,bun_zipper.ply" if "--scenes" not in words else "")
    return f"draw {option('--draw', '0')}: {scenes}" + (f" (full: {full.replace(',', ', ')})" if full else "")


def row(name: str, records: list[dict[str, Any]], command: str) -> list[object]:
    """The report ``name``'s line of the table (its ``records`` and the ``command`` that wrote them)."""
    reliable = [e for e in records if e["reliable"] and e.get("within_3_sigma")]
    within = " / ".join(str(sum(e["within_3_sigma"][k] for e in reliable)) for k in range(3))
    return [
        f"[{name}]({name}.md)",
        clouds(command),
        len(records),
        sum(bool(e.get("right")) for e in records),
        sum(bool(e.get("right")) and e["reliable"] for e in records),
        sum(e["reliable"] and not e.get("right") for e in records),
        sum(bool(e.get("right")) and not e["reliable"] for e in records),
        search_misses(records),
        f"{within} of {len(reliable)}",
    ]


def outside_3_sigma(name: str, records: list[dict[str, Any]]) -> list[list[object]]:
    """The reliable results with an error beyond three of their sigmas in some component: which,
    and by how many sigmas (rotation / scale / translation, as ``within_3_sigma`` compares)."""
    out: list[list[object]] = []
    for e in records:
        if not (e["reliable"] and e.get("within_3_sigma")) or all(e["within_3_sigma"]):
            continue
        ratios = sigma_ratios(name, e)
        beyond = ", ".join(
            f"{component} {ratio:.2f} sigma"
            for component, ratio, inside in zip(COMPONENTS, ratios, e["within_3_sigma"], strict=True)
            if not inside
        )
        out.append([name, e["suite"], e["case"], e["cap"], beyond])
    return out


def per_scene(group: str, records: list[dict[str, Any]]) -> list[list[object]]:
    """Per scene of the scene suites: cases, right, successes, and where the data determine the pose."""
    scenes: dict[str, list[dict[str, Any]]] = {}
    for e in records:
        if e["suite"] in SCENE_SUITES:
            scenes.setdefault(e["scene"], []).append(e)
    return [
        [
            scene,
            group,
            len(cases),
            sum(bool(e["right"]) for e in cases),
            sum(bool(e["right"]) and e["reliable"] for e in cases),
            sum(pose_determined(e) for e in cases),
        ]
        for scene, cases in scenes.items()
    ]


def main(argv: list[str] | None = None) -> int:
    parser = script.parser(__file__, __doc__, "the committed development report alone", report=True)
    parser.add_argument(
        "--reports", type=Path, default=REPORTS_DIR, metavar="DIR", help="where the JSON reports are (docs/)"
    )
    args = script.parse(parser, argv)
    groups = {"development": DEVELOPMENT_REPORTS, "held-out": HELD_OUT_REPORTS}
    if args.quick:
        groups = {"development": DEVELOPMENT_REPORTS[:1], "held-out": ()}
    rows: list[list[object]] = []
    outside: list[list[object]] = []
    every: dict[str, list[dict[str, Any]]] = {}
    for group, names in groups.items():
        every[group] = []
        for name in names:
            path = args.reports / f"{name}.json"
            if not path.is_file():
                return script.skip(args, f"no report {path}: run benchmarks/trustworthy.py first")
            document = json.loads(path.read_text())
            rows.append(row(name, document["records"], document["command"]))
            outside += outside_3_sigma(name, document["records"])
            every[group] += document["records"]
    header = [
        "report",
        "clouds",
        "cases",
        "right",
        "success (right, reliable)",
        "wrong and reliable",
        "right, refused",
        "search misses (refused where determined)",
        "reliable within 3 sigma (rot / scale / trans)",
    ]
    totals = [
        f"**{group}**: {len(every[group])} cases, "
        f"{sum(bool(e.get('right')) and e['reliable'] for e in every[group])} successes, "
        f"{sum(e['reliable'] and not e.get('right') for e in every[group])} wrong and reliable"
        for group in groups
        if every[group]
    ]
    suites: dict[str, dict[str, list[object]]] = {}
    for group, records in every.items():
        for suite, cases, decided, success in determined(records)[1]:
            suites.setdefault(str(suite), {})[group] = [cases, decided, success]
    decided_rows = [
        [suite, *(f"{by[g][2]} ({by[g][0]} cases)" if g in by else "-" for g in groups)]
        for suite, by in suites.items()
    ]
    summary = (
        "; ".join(totals)
        + ".\n\nWhere the data determine the pose (the start at the truth is right and reliable), the"
        " search's successes among those cases per suite (how many cases the suite had):\n\n"
        + "\n".join(markdown_table(["suite", *groups], decided_rows))
        + f"\n\nThe {len(outside)} reliable results with an error beyond 3 of their sigmas:\n\n"
        + "\n".join(markdown_table(["report", "suite", "case", "resolution", "beyond 3 sigma"], outside))
        + "\n\nPer scene of the scene suites (crops both ways, sparse maps, frames, jumps):\n\n"
        + "\n".join(
            markdown_table(
                [
                    "scene",
                    "draws",
                    "cases",
                    "right",
                    "success (right, reliable)",
                    "determined (truth start right, reliable)",
                ],
                [line for group, records in every.items() for line in per_scene(group, records)],
            )
        )
        + "\n\nPer report:"
    )
    write_report(args.out, TITLE, script.command_line(args), summary, (header, rows), [])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
