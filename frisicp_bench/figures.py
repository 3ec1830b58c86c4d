"""PNG figures of a run (matplotlib, Agg): convergence curves and registration pictures.

Like the paper: convergence of each method on one case (Figs 2-3: 2-D deer and 3-D bunny near
s = 0.8), model and data before/after registration (Figs 1 and 4), plus the success of every
method at every scale.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display on CI or servers
import matplotlib.pyplot as plt
import numpy as np

from frisicp_core import FloatArray, Similarity

from .cases import Case, Family
from .runner import BenchmarkRun, CaseRecord
from .summary import select
from .tables import ordered_methods

COLOURS = {
    "frisicp": "tab:red",
    "frisicp-default": "tab:orange",
    "icp": "tab:blue",
    "scale-icp": "tab:green",
    "bounded-icp": "tab:purple",
    "open3d": "tab:gray",
}
MODEL_COLOUR, DATA_COLOUR = "tab:red", "tab:blue"  # the paper's colours: model red, data blue
# Points drawn per set in 3-D pictures: enough to show the shape, few enough for small files.
MAX_DRAWN_POINTS = 1800
DPI = 90


def write_figures(run: BenchmarkRun, out_dir: Path) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for kind, stem in (("2-D", "2d"), ("3-D", "3d")):
        families = [f for f in run.families if f.kind == kind]
        if not families:
            continue
        # The paper's Fig. 2 is a different-instance deer pair, Fig. 3 the bunny: prefer those.
        shown = _preferred(families, ("deer 2→1", "bunny"))
        case = run.case(shown.name, _scale_near(run, shown.name, 0.8))
        written.append(_save(convergence_figure(run, case), out_dir / f"convergence_{stem}.png"))
        small = run.case(shown.name, _scale_near(run, shown.name, 0.1))
        written.append(_save(registration_figure(run, small), out_dir / f"registration_{stem}.png"))
        for family in families:
            if family.figure:  # the partial-overlap experiments: one picture each
                scans = run.case(family.name, _scale_near(run, family.name, 0.8))
                written.append(_save(registration_figure(run, scans), out_dir / family.figure))
    written.append(_save(success_figure(run), out_dir / "success_by_scale.png"))
    return written


def _preferred(families: list[Family], names: tuple[str, ...]) -> Family:
    by_name = {f.name: f for f in families}
    return next((by_name[n] for n in names if n in by_name), families[-1])


def _scale_near(run: BenchmarkRun, family: str, wanted: float) -> float:
    return min((c.scale for c in run.cases if c.family.name == family), key=lambda s: abs(s - wanted))


def _save(figure: plt.Figure, path: Path) -> Path:
    figure.savefig(path, dpi=DPI, bbox_inches="tight")
    plt.close(figure)
    return path


def convergence_figure(run: BenchmarkRun, case: Case) -> plt.Figure:
    """Each method's forward RMS per iteration against time and against iteration count."""
    figure, (by_time, by_iteration) = plt.subplots(1, 2, figsize=(12, 4.5))
    for record in _records_of(run, case):
        if not record.history:
            continue  # Open3D reports no per-iteration errors
        seconds = [p.seconds for p in record.history]
        rms = [p.rms for p in record.history]
        style = {"color": COLOURS.get(record.method), "label": run.method_label(record.method), "lw": 1.6}
        by_time.plot(seconds, rms, marker=".", ms=3, **style)
        by_iteration.plot([p.iteration for p in record.history], rms, marker=".", ms=3, **style)
    family = case.family
    for axes, xlabel in ((by_time, "time since start (s)"), (by_iteration, "iteration (all levels)")):
        axes.set_yscale("log")
        axes.set_xlabel(xlabel)
        axes.set_ylabel(f"forward RMS ({family.units})")
        axes.grid(True, which="both", alpha=0.3)
    by_iteration.legend(loc="best", fontsize=9)
    figure.suptitle(
        f"Convergence on {family.name}, s = {case.scale:g} ({family.data.shape[0]} data points). "
        "FRISICP's coarse levels use fewer points, hence the jumps.",
        fontsize=10,
    )
    return figure


def _records_of(run: BenchmarkRun, case: Case) -> list[CaseRecord]:
    records = {r.method: r for r in run.records if r.family == case.family.name and r.scale == case.scale}
    return [records[k] for k in ordered_methods(run) if k in records]


def registration_figure(run: BenchmarkRun, case: Case) -> plt.Figure:
    """Model (red) and data (blue) before registration and after each method, like Figs 1 and 4."""
    records = _records_of(run, case)
    panels: list[tuple[str, Similarity | None, CaseRecord | None]] = [
        ("before registration", Similarity.identity(case.family.dim), None)
    ]
    panels += [(run.method_label(r.method), r.estimate, r) for r in records]
    columns = 4 if len(panels) > 6 else 3
    rows = -(-len(panels) // columns)
    figure, axes_grid = plt.subplots(rows, columns, figsize=(4 * columns, 3.8 * rows))
    model = _thinned(case.family.model)
    data = _thinned(case.data)
    for axes, (title, estimate, record) in zip(axes_grid.ravel(), panels, strict=False):
        axes.set_title(title + _verdict(record), fontsize=10)
        axes.plot(*_view(model).T, ".", color=MODEL_COLOUR, ms=1.0)
        if estimate is not None:
            axes.plot(*_view(estimate.apply(data)).T, ".", color=DATA_COLOUR, ms=1.0)
        axes.set_aspect("equal", adjustable="datalim")
        axes.set_xticks([])
        axes.set_yticks([])
    for axes in axes_grid.ravel()[len(panels) :]:
        axes.axis("off")
    family = case.family
    view = "front view (x, y)" if family.dim == 3 else "plane"
    figure.suptitle(f"{family.name}, s = {case.scale:g}: model red, data blue; {view}", fontsize=11)
    return figure


def _verdict(record: CaseRecord | None) -> str:
    if record is None:
        return ""
    if record.estimate is None:
        return f"\nfailed: {record.failure}"
    return (
        f"\n{'success' if record.success else 'FAIL'}: rot {record.rotation_deg:.2g}°, "
        f"scale {record.scale_error:.1%}"
    )


def _thinned(points: FloatArray) -> FloatArray:
    """At most MAX_DRAWN_POINTS rows, evenly spaced in the input order (deterministic)."""
    if points.shape[0] <= MAX_DRAWN_POINTS:
        return points
    return points[np.linspace(0, points.shape[0] - 1, MAX_DRAWN_POINTS).astype(int)]


def _view(points: FloatArray) -> FloatArray:
    """The two coordinates drawn: x and y (the bunny's y axis points up)."""
    return points[:, :2]


def success_figure(run: BenchmarkRun) -> plt.Figure:
    """Per method and scale, the share of families where the method succeeds."""
    keys = ordered_methods(run)
    scales = sorted({c.scale for c in run.cases})
    figure, panels = plt.subplots(1, 2, figsize=(12, 0.5 * len(keys) + 1.8), sharey=True)
    for axes, true_pose in zip(panels, (True, False), strict=False):
        grid = np.full((len(keys), len(scales)), np.nan)
        for i, key in enumerate(keys):
            for j, scale in enumerate(scales):
                cell = [r for r in select(run, method=key, true_pose=true_pose) if r.scale == scale]
                if cell:
                    grid[i, j] = np.mean([r.success for r in cell])
        image = axes.imshow(grid, vmin=0, vmax=1, cmap="RdYlGn", aspect="auto")
        axes.set_xticks(range(len(scales)), [f"{s:g}" for s in scales], fontsize=8)
        axes.set_yticks(range(len(keys)), [run.method_label(k) for k in keys])
        axes.set_xlabel("scale factor s")
        families = sorted({r.family for r in select(run, true_pose=true_pose)})
        axes.set_title(
            ("true pose: " if true_pose else "against the reference: ") + ", ".join(families),
            fontsize=8,
            wrap=True,
        )
    figure.colorbar(image, ax=panels, label="share of families with success")
    return figure
