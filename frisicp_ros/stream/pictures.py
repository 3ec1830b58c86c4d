"""Pictures of registrations, for people who would rather look than read (matplotlib, Agg).

- :func:`alignment_picture`: the data and the model before and after, in three orthogonal views
  (one for 2-D points), and the histogram of the aligned data's distances to the model
  (``frisicp register --plot``, the demo's last alignment);
- :func:`stream_picture`: a stream's results over time from the bag mode's JSON lines: scale,
  rotation angle, RMS, registration time, and the verdict of every pair (``frisicp bag --plot``).

matplotlib is imported inside the functions, with the Agg backend (no display needed), so
nothing else in the package pays for it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from frisicp_core import NearestNeighbors, Similarity

_MAX_DRAWN = 3000  # points drawn per cloud and view: enough to see a shape, small files
_VIEWS = ((0, 1, "x", "y"), (0, 2, "x", "z"), (1, 2, "y", "z"))
MODEL_COLOUR, DATA_COLOUR = "#888888", "#d62728"


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _thinned(points: np.ndarray, seed: int = 0) -> np.ndarray:
    if len(points) <= _MAX_DRAWN:
        return points
    return points[np.random.default_rng(seed).choice(len(points), _MAX_DRAWN, replace=False)]


def alignment_picture(
    data: np.ndarray, model: np.ndarray, similarity: Similarity, path: str | Path, title: str = ""
) -> Path:
    """Write a PNG: rows "before" (data as given) and "after" (s R data + t) over the model, in
    the x-y, x-z and y-z views (x-y only in 2-D), and the distances of the aligned data to the
    model. Returns the path."""
    plt = _pyplot()
    aligned = similarity.apply(data)
    squared, _ = NearestNeighbors(model).query(aligned)
    distances = np.sqrt(squared)
    views = _VIEWS if data.shape[1] == 3 else _VIEWS[:1]
    figure, axes = plt.subplots(2, len(views) + 1, figsize=(4.2 * (len(views) + 1), 7.6), squeeze=False)
    drawn_model = _thinned(model, 1)
    for row, (label, points) in enumerate((("before", data), ("after", aligned))):
        drawn = _thinned(points, 2)
        for column, (i, j, x_name, y_name) in enumerate(views):
            ax = axes[row][column]
            ax.scatter(drawn_model[:, i], drawn_model[:, j], s=1, c=MODEL_COLOUR, label="model", linewidths=0)
            ax.scatter(drawn[:, i], drawn[:, j], s=1, c=DATA_COLOUR, label="data", linewidths=0)
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xlabel(x_name)
            ax.set_ylabel(y_name)
            ax.set_title(f"{label}: {x_name}-{y_name}")
        axes[row][0].legend(loc="upper right", markerscale=8, fontsize=8)
    histogram = axes[0][len(views)]
    finite = distances[np.isfinite(distances)]
    histogram.hist(finite, bins=60, color=DATA_COLOUR)
    histogram.set_title("aligned data: distance to the model")
    histogram.set_xlabel("distance (model units)")
    histogram.set_ylabel("points")
    text = axes[1][len(views)]
    text.axis("off")
    angle = np.degrees(similarity.rotation_angle())
    lines = [
        f"scale {similarity.scale:.6g}",
        f"rotation {angle:.3f} deg",
        "translation " + ", ".join(f"{v:.4g}" for v in similarity.translation),
        f"median distance {np.median(finite):.4g}" if finite.size else "no distances",
        f"90 % of points within {np.quantile(finite, 0.9):.4g}" if finite.size else "",
    ]
    text.text(0.0, 0.95, "\n".join(lines), va="top", family="monospace", fontsize=10)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    return _save(figure, plt, path)


def stream_picture(records: Sequence[Mapping[str, Any]], path: str | Path, title: str = "") -> Path:
    """Write a PNG of a stream's results over time (the bag mode's JSON lines, ``pair_record``):
    scale (with its 1-sigma band when known), rotation angle, RMS and registration time of the
    registered pairs, and every pair's verdict; ``title`` (the bag's name) heads the counts.
    Returns the path."""
    plt = _pyplot()
    if not records:
        raise ValueError("no results to plot")
    start = min(int(r["stamp_ns"]) for r in records)
    time_of = {id(r): (int(r["stamp_ns"]) - start) * 1e-9 for r in records}
    registered = [r for r in records if "scale" in r]
    usable = [r for r in registered if r.get("ok")]
    figure, axes = plt.subplots(5, 1, figsize=(9, 10), sharex=True)
    t = np.array([time_of[id(r)] for r in usable])
    scale = np.array([r["scale"] for r in usable], dtype=np.float64)
    axes[0].plot(t, scale, ".-", color="#1f77b4", markersize=3, linewidth=0.8)
    sigma = np.array([(r.get("uncertainty") or {}).get("scale") or np.nan for r in usable], dtype=np.float64)
    if np.any(np.isfinite(sigma)):
        # An explicit mask: matplotlib 3.6 (setup.py's floor) fails on unmasked arrays without
        # one (a 0-d `where`), and the band should skip results without a sigma anyway.
        known = np.isfinite(sigma)
        band = (scale * (1 - sigma), scale * (1 + sigma))
        axes[0].fill_between(t, *band, where=known, alpha=0.3, label="1 sigma")
        axes[0].legend(loc="best", fontsize=8)
    axes[0].set_ylabel("scale s")
    axes[1].plot(t, [_rotation_deg(r) for r in usable], ".-", color="#2ca02c", markersize=3, linewidth=0.8)
    axes[1].set_ylabel("rotation (deg)")
    axes[2].plot(t, [r["rms"] for r in usable], ".-", color="#9467bd", markersize=3, linewidth=0.8)
    axes[2].set_ylabel("RMS")
    times = [(time_of[id(r)], r["seconds"] * 1e3) for r in registered if r.get("seconds") is not None]
    if times:
        axes[3].plot(*zip(*times, strict=True), ".", color="#ff7f0e", markersize=3)
    axes[3].set_yscale("log")
    axes[3].set_ylabel("registration time (ms)")
    verdicts = (
        ("ok", "#2ca02c", lambda r: r.get("ok")),
        ("unreliable", "#ff7f0e", lambda r: "scale" in r and not r.get("ok")),
        ("rejected", "#d62728", lambda r: "rejection" in r),
    )
    for row, (label, colour, chosen) in enumerate(verdicts):
        marks = [time_of[id(r)] for r in records if chosen(r)]
        axes[4].plot(
            marks, [row] * len(marks), "|", color=colour, markersize=12, label=f"{label} ({len(marks)})"
        )
    axes[4].set_yticks(range(len(verdicts)), [v[0] for v in verdicts])
    axes[4].set_ylim(-0.7, len(verdicts) - 0.3)
    axes[4].set_xlabel("data cloud time in the bag (s)")
    axes[4].set_ylabel("verdict")
    for ax in axes:
        ax.grid(alpha=0.3)
    counts = f"{len(records)} pairs, {len(usable)} usable results"
    figure.suptitle(f"{title}: {counts}" if title else counts)
    figure.tight_layout()
    return _save(figure, plt, path)


def _rotation_deg(record: Mapping[str, Any]) -> float:
    rotation = np.asarray(record["rotation"], dtype=np.float64)
    return float(np.degrees(Similarity(1.0, rotation, np.zeros(len(rotation))).rotation_angle()))


def _save(figure: Any, plt: Any, path: str | Path) -> Path:
    target = Path(path)
    try:
        figure.savefig(target, dpi=72)
    finally:
        plt.close(figure)
    return target
