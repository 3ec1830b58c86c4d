"""1-NN libraries on FRISICP's workload: build and query times, ratios to pykdtree, exactness.

Sections (``--sections``, default all):

* ``nn``: for every installed candidate, build time and 1-NN query time (all points of one set
  queried against a tree on the other, results converted to the core's contract: float64
  squared distances, int64 indices) on
  (a) the node's workload: two 3-D clouds of 20,000 points (a lidar-like scan of a room and the
  node benchmark's closed surface), and their 1,000 and 4,472 point levels; queries aligned
  (the data on the model, as in most iterations) and misaligned (a far-off pose, as in the
  first iterations of a cold start);
  (b) the Stanford bunny (35,947 points; skipped with a message when the data folder lacks it);
  (c) 2-D contours of 2,000 and 5,000 points.
  With 1 thread and with 2 threads where the library allows. Candidates are interleaved
  within every repeat (rotating order) and the table gives medians and the ratio
  time(pykdtree) / time(candidate) from the same run: > 1 means faster than pykdtree. On a
  shared machine only these within-run ratios are meaningful.
  Every candidate's answer is checked against scipy's cKDTree (index mismatches that are not
  ties of equal distance are errors).
* ``register``: ``frisicp_core.register`` itself, with its NearestNeighbors replaced by each
  exact candidate (1 thread, as the node runs): the node's workload cold and warm, the bunny.
  The replacement is a subclass of the public ``NearestNeighbors`` that answers its whole
  contract (``query``, ``query_k``, ``spacing``) with the candidate, put in the core's place by
  ``frisicp_bench.neighbours`` (the core has no hook for it).
* ``split``: how much of a ``register`` call is tree building vs querying (pykdtree).
* ``downsample``: capping a 100k-point cloud to 20k random points, and voxel-grid
  down-sampling it, in numpy (and in small_gicp / kiss-icp for reference).

(The ``register`` and ``split`` variants with every level's points put in Morton order are gone:
``register`` now puts scattered clouds in that order itself, ``frisicp_core.sampling.in_spatial_order``;
the ``nn`` section still measures what the order is worth to the queries.)

Usage: python benchmarks/nn_backends.py [--repeats 7] [--sections nn,register,split,downsample]
                                        [--threads 1,2] [--data DIR] [--json out.json]
       python benchmarks/nn_backends.py --quick   # every section once, on clouds of 3,000 points
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
from scipy.spatial import KDTree, cKDTree
from threadpoolctl import threadpool_limits

from frisicp_bench import script
from frisicp_bench.neighbours import neighbours_class
from frisicp_bench.report import markdown_table
from frisicp_core import (
    NearestNeighbors,
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    bumpy_surface,
    closed_contour,
    read_points,
    register,
)
from frisicp_core.sampling import downsample, level_sizes, spatial_order


@dataclass(frozen=True)
class Sizes:
    """Point counts of the workloads: the full run's, or (``QUICK``) a smoke run's."""

    scan: int = 100_000  # a simulated scan or surface sample, before the cap
    cap: int = 20_000  # the node's max_points
    contours: tuple[int, ...] = (2000, 5000)
    bunny: int | None = None  # the bunny's points kept (None: all 35,947)


QUICK = Sizes(scan=10_000, cap=3000, contours=(1000,), bunny=3000)

Tree = object
BRUTE_FORCE_MAX = 5000  # faiss' exact index is O(n m): timed on the small sets only (20k: ~1.5 s)
QueryResult = tuple[np.ndarray, np.ndarray]


# ---------------------------------------------------------------------------------------------
# Candidates: build(points, threads) -> tree; query(tree, queries, threads, k=1) -> (d2 f64, idx
# i64): (n,) arrays for k = 1, (n, k) arrays, nearest first, for k > 1.


@dataclass
class Candidate:
    name: str
    build: Callable[[np.ndarray, int], Tree]
    query: Callable[..., QueryResult]
    exact: bool = True
    threaded: bool = True
    dims: tuple[int, ...] = (2, 3)
    note: str = ""


def _pykdtree(dtype: type) -> Candidate:
    from pykdtree.kdtree import KDTree as PyKDTree

    # pykdtree parallelises its queries with OpenMP; the thread count is set around each section
    # with threadpoolctl (as OMP_NUM_THREADS does for the node).
    def build(points: np.ndarray, threads: int) -> Tree:
        return PyKDTree(np.ascontiguousarray(points, dtype=dtype), leafsize=16)

    def query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
        d2, idx = tree.query(np.ascontiguousarray(queries, dtype=dtype), k=k, sqr_dists=True)
        return d2.astype(np.float64), idx.astype(np.int64)

    name = "pykdtree" if dtype is np.float64 else "pykdtree-f32"
    note = "" if dtype is np.float64 else "float32 copies of points and queries"
    return Candidate(name, build, query, exact=dtype is np.float64, note=note)


def _scipy_query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
    """scipy's cKDTree and KDTree answer alike: squared distances, indices."""
    d, idx = tree.query(queries, k=k, workers=threads)
    return d * d, idx


def _columns(d2: np.ndarray, idx: np.ndarray, k: int) -> QueryResult:
    """(n, k) answers as the contract has them: the first column alone for k = 1."""
    return (d2[:, 0], idx[:, 0]) if k == 1 else (d2, idx)


def _ckdtree() -> Candidate:
    def build(points: np.ndarray, threads: int) -> Tree:
        return cKDTree(points, leafsize=16, balanced_tree=False, compact_nodes=False)

    return Candidate("scipy-cKDTree", build, _scipy_query, note="as frisicp_core builds it; workers=threads")


def _scipy_kdtree() -> Candidate:
    def build(points: np.ndarray, threads: int) -> Tree:
        return KDTree(points)  # scipy defaults: balanced, compact nodes, leafsize 10

    return Candidate("scipy-KDTree", build, _scipy_query, note="scipy.spatial.KDTree, default build options")


def _small_gicp() -> Candidate:
    import small_gicp

    def build(points: np.ndarray, threads: int) -> Tree:
        if points.shape[1] == 2:  # small_gicp takes (n, 3|4) only: 2-D sets get z = 0
            points = np.column_stack((points, np.zeros(points.shape[0])))
        return small_gicp.KdTree(np.ascontiguousarray(points, dtype=np.float64), num_threads=threads)

    def query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
        if queries.shape[1] == 2:
            queries = np.column_stack((queries, np.zeros(queries.shape[0])))
        queries = np.ascontiguousarray(queries, dtype=np.float64)
        if k > 1:
            idx, d2 = tree.batch_knn_search(queries, k, num_threads=threads)
            return np.asarray(d2, dtype=np.float64), np.asarray(idx, dtype=np.int64)
        idx, d2 = tree.batch_nearest_neighbor_search(queries, num_threads=threads)
        # The binding returns Python lists (not arrays, despite its docstring): converting is
        # part of the cost.
        return np.asarray(d2, dtype=np.float64), np.asarray(idx, dtype=np.int64)

    return Candidate("small_gicp", build, query, note="2-D padded with z = 0; results come as lists")


def _pynanoflann() -> Candidate:
    import pynanoflann

    def build(points: np.ndarray, threads: int) -> Tree:
        tree = pynanoflann.KDTree(n_neighbors=1, leaf_size=10)
        tree.fit(np.ascontiguousarray(points, dtype=np.float64))
        return tree

    def query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
        d, idx = tree.kneighbors(np.ascontiguousarray(queries, dtype=np.float64), k, n_jobs=threads)
        # it takes the square root of nanoflann's d^2
        return _columns(d * d, idx.astype(np.int64), k)

    return Candidate("pynanoflann", build, query)


def _napf() -> Candidate:
    import napf

    def build(points: np.ndarray, threads: int) -> Tree:
        return napf.KDT(
            np.ascontiguousarray(points, dtype=np.float64), metric=2, leaf_size=10, nthread=threads
        )

    def query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
        d2, idx = tree.knn_search(np.ascontiguousarray(queries, dtype=np.float64), k, nthread=threads)
        return _columns(d2, idx.astype(np.int64), k)

    return Candidate("napf", build, query)


def _sklearn() -> Candidate:
    from sklearn.neighbors import KDTree as SkKDTree

    def build(points: np.ndarray, threads: int) -> Tree:
        return SkKDTree(points, leaf_size=16)

    def query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
        d, idx = tree.query(queries, k=k)
        return _columns(d * d, idx.astype(np.int64), k)

    return Candidate("sklearn-KDTree", build, query, threaded=False, note="single-threaded queries")


def _faiss() -> Candidate:
    import faiss

    def build(points: np.ndarray, threads: int) -> Tree:
        faiss.omp_set_num_threads(threads)
        index = faiss.IndexFlatL2(points.shape[1])
        index.add(np.ascontiguousarray(points, dtype=np.float32))
        return index

    def query(tree: Tree, queries: np.ndarray, threads: int, k: int = 1) -> QueryResult:
        faiss.omp_set_num_threads(threads)
        d2, idx = tree.search(np.ascontiguousarray(queries, dtype=np.float32), k)
        return _columns(d2.astype(np.float64), idx.astype(np.int64), k)

    return Candidate(
        "faiss-FlatL2",
        build,
        query,
        exact=False,
        note="brute force O(n m), float32 (its exact index; the fast ones are approximate)",
    )


def candidates() -> tuple[list[Candidate], list[str]]:
    """The installed candidates and a line for each one that is not."""
    found, missing = [], []
    for make, module in (
        (lambda: _pykdtree(np.float64), "pykdtree"),
        (lambda: _pykdtree(np.float32), "pykdtree"),
        (_ckdtree, "scipy"),
        (_scipy_kdtree, "scipy"),
        (_small_gicp, "small_gicp"),
        (_pynanoflann, "pynanoflann"),
        (_napf, "napf"),
        (_sklearn, "sklearn"),
        (_faiss, "faiss"),
    ):
        try:
            found.append(make())
        except ImportError as error:
            missing.append(f"{module}: not installed ({error})")
    return found, missing


# ---------------------------------------------------------------------------------------------
# Workloads


def rotation(axis: tuple[float, float, float], degrees: float) -> np.ndarray:
    return axis_angle_rotation(axis, np.deg2rad(degrees))


def rotation_2d(degrees: float) -> np.ndarray:
    a = np.deg2rad(degrees)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def lidar_scan(n: int, sensor: np.ndarray, yaw_deg: float, seed: int) -> np.ndarray:
    """About n points of a 32-ring spinning lidar at ``sensor`` in a room with pillars, world frame.

    Ground at z = 0, walls of a 60 x 36 m box 6 m high, eight pillars and two parked boxes;
    1 cm range noise. Density falls off with range as in a real scan.
    """
    rng = np.random.default_rng(seed)
    rings = 32
    elevation = np.deg2rad(np.linspace(-25.0, 8.0, rings))
    per_ring = int(np.ceil(n * 1.35 / rings))  # some rays escape over the walls
    azimuth = np.deg2rad(yaw_deg) + np.linspace(0, 2 * np.pi, per_ring, endpoint=False)
    el, az = np.meshgrid(elevation, azimuth, indexing="ij")
    az = az + rng.uniform(-0.002, 0.002, size=az.shape)
    d = np.stack((np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), axis=-1).reshape(-1, 3)
    o = np.asarray(sensor, dtype=float)
    t = np.full(d.shape[0], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        ground = -o[2] / d[:, 2]
        t = np.where((d[:, 2] < 0) & (ground > 0), np.minimum(t, ground), t)
        for axis, low, high in ((0, -25.0, 35.0), (1, -14.0, 22.0)):
            wall = np.where(d[:, axis] > 0, (high - o[axis]) / d[:, axis], (low - o[axis]) / d[:, axis])
            hit_z = o[2] + wall * d[:, 2]
            t = np.where((wall > 0) & (hit_z < 6.0), np.minimum(t, wall), t)
        for cx, cy in ((5, 4), (-6, 7), (12, -5), (-10, -8), (20, 10), (-18, 3), (8, 15), (25, -10)):
            # vertical cylinder of radius 0.4 m: |o_xy + t d_xy - c|^2 = r^2
            px, py = o[0] - cx, o[1] - cy
            a = d[:, 0] ** 2 + d[:, 1] ** 2
            b = 2 * (px * d[:, 0] + py * d[:, 1])
            c = px * px + py * py - 0.16
            disc = b * b - 4 * a * c
            hit = (disc > 0) & (a > 1e-12)
            tc = (-b - np.sqrt(np.where(hit, disc, 0))) / (2 * np.where(a > 1e-12, a, 1))
            t = np.where(hit & (tc > 0), np.minimum(t, tc), t)
        for lo, hi in (((3, -4, 0), (7.5, -2.2, 1.5)), ((-12, 10, 0), (-7.5, 11.8, 1.6))):  # parked cars
            lo_a, hi_a = np.array(lo, float), np.array(hi, float)
            t1 = (lo_a - o) / d
            t2 = (hi_a - o) / d
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (near <= far) & (near > 0)
            t = np.where(hit, np.minimum(t, near), t)
    ok = np.isfinite(t) & (t < 100.0)
    t = t[ok] + rng.normal(scale=0.01, size=ok.sum())
    points = o + t[:, None] * d[ok]
    if points.shape[0] > n:
        points = points[np.sort(rng.choice(points.shape[0], n, replace=False))]
    return points


@dataclass
class Workload:
    """A model (tree) and the data queried against it: aligned and misaligned."""

    group: str
    name: str
    model: np.ndarray
    aligned: np.ndarray  # data mapped onto the model by the true pose
    misaligned: np.ndarray  # data under a far-off pose (cold start)
    extra: dict = field(default_factory=dict)


def node_workloads(sizes: Sizes) -> list[Workload]:
    """(a) The node's clouds, each capped to 20k random points, at the three level sizes."""
    rng = np.random.default_rng(7)
    out = []
    # Lidar-like: two scans 1.5 m apart (model: the map scan; data: the new scan, already in the
    # map frame when aligned). Both are random 20k subsets of ~100k-point scans, like max_points.
    model_full = lidar_scan(sizes.scan, np.array([0.0, 0.0, 1.8]), 0.0, seed=1)
    data_full = lidar_scan(sizes.scan, np.array([1.5, 0.4, 1.8]), 3.0, seed=2)
    # Node-benchmark surface (benchmarks/node_latency.py): bumpy_surface clouds.
    surf_model = bumpy_surface(sizes.scan, seed=0)
    surf_data = bumpy_surface(sizes.scan, seed=1) + rng.normal(scale=0.002, size=(sizes.scan, 3))
    far3 = Similarity(1.3, rotation((0.2, 0.3, 1.0), 75.0), np.array([0.3, -0.2, 0.1]))
    for label, model_all, data_all, far in (
        ("lidar", model_full, data_full, Similarity(1.2, rotation((0.1, 0.1, 1.0), 60.0), [4.0, -3.0, 0.5])),
        ("surface", surf_model, surf_data, far3),
    ):
        model_capped = downsample(model_all, sizes.cap, rng)
        data_capped = downsample(data_all, sizes.cap, rng)
        for size in level_sizes(sizes.cap, sizes.cap, 3, 1000):
            model = downsample(model_capped, size, rng)
            data = downsample(data_capped, size, rng)
            out.append(Workload("node", f"{label} {size}", model, data, far.apply(data)))
        # The same capped sets with model and data each in Morton order (the core's
        # spatial_order): what spatially coherent queries and tree points are worth (a real scan
        # is ring-ordered, bumpy_surface is not; register orders scattered clouds itself).
        model = model_capped[spatial_order(model_capped)]
        data = data_capped[spatial_order(data_capped)]
        out.append(Workload("order", f"{label} {sizes.cap} Morton-ordered", model, data, far.apply(data)))
    return out


def read_bunny(data_dir: Path, sizes: Sizes) -> np.ndarray | None:
    """The bunny reconstruction (metres; ``sizes.bunny`` random points of it), or None, saying so,
    when the data folder lacks it."""
    path = data_dir / "bunny" / "bun_zipper.ply"
    if not path.exists():
        print(f"# bunny: {path} is absent; the bunny rows are skipped", file=sys.stderr)
        return None
    bunny = read_points(path)
    return bunny if sizes.bunny is None else downsample(bunny, sizes.bunny, np.random.default_rng(0))


def bunny_workloads(bunny: np.ndarray | None) -> list[Workload]:
    """(b) The bunny against a noisy copy; the registration's three level sizes."""
    if bunny is None:
        return []
    rng = np.random.default_rng(3)
    spread = float(np.sqrt(((bunny - bunny.mean(0)) ** 2).sum(1).mean()))
    data_all = bunny + rng.normal(scale=0.002 * spread, size=bunny.shape)
    far = Similarity(0.6, rotation((0.3, 1.0, 0.2), 40.0), bunny.mean(0) * 0.3 + 0.05)
    out = []
    for size in level_sizes(bunny.shape[0], bunny.shape[0], 3, 1000):
        model = downsample(bunny, size, rng)
        data = downsample(data_all, size, rng)
        out.append(Workload("bunny", f"bunny {size}", model, data, far.apply(data)))
    return out


def contour_workloads(sizes: Sizes) -> list[Workload]:
    """(c) 2-D closed contours: the data re-sampled at other angles, with noise."""
    rng = np.random.default_rng(5)
    out = []
    for size in sizes.contours:
        model = closed_contour(size)
        shifted = closed_contour(size * 7)[3::7][:size]  # other samples of the same curve
        data = shifted + rng.normal(scale=0.002, size=shifted.shape)
        far = Similarity(0.7, rotation_2d(120.0), np.array([0.4, -0.3]))
        out.append(Workload("contour", f"2-D contour {size}", model, data, far.apply(data)))
    return out


# ---------------------------------------------------------------------------------------------
# Timing


# With one thread the process CPU time is what is compared: on a shared machine the wall time
# also counts the time the process waited for a core. With two threads only wall time shows the
# speed-up, and it is noisier.
CLOCK = {"cpu": time.process_time, "wall": time.perf_counter}


def timed(action: Callable[[], object], clock: str = "cpu") -> tuple[float, object]:
    now = CLOCK[clock]
    start = now()
    value = action()
    return now() - start, value


def check_exact(result: QueryResult, reference: QueryResult) -> tuple[int, int, float]:
    """(index mismatches, of which not ties, max relative squared-distance error)."""
    d2, idx = result
    ref_d2, ref_idx = reference
    if idx.dtype != np.int64 or d2.dtype != np.float64 or idx.shape != ref_idx.shape:
        raise AssertionError(f"contract broken: {d2.dtype} {idx.dtype} {idx.shape}")
    rel = np.abs(d2 - ref_d2) / np.maximum(ref_d2, 1e-300)
    differ = idx != ref_idx
    wrong = differ & (rel > 1e-9)
    return int(differ.sum()), int(wrong.sum()), float(rel.max())


def bench_nn(cands: list[Candidate], workloads: list[Workload], threads: int, repeats: int) -> list[dict]:
    rows = []
    for work in workloads:
        dim = work.model.shape[1]
        usable = [
            c
            for c in cands
            if dim in c.dims
            and (threads == 1 or c.threaded)
            and (c.name != "faiss-FlatL2" or work.model.shape[0] <= BRUTE_FORCE_MAX)
        ]
        reference = {
            kind: (lambda t, q: (t.query(q, k=1)[0] ** 2, t.query(q, k=1)[1]))(cKDTree(work.model), q)
            for kind, q in (("aligned", work.aligned), ("misaligned", work.misaligned))
        }
        times: dict[str, dict[str, list[float]]] = {
            c.name: {"build": [], "aligned": [], "misaligned": []} for c in usable
        }
        checks: dict[str, dict[str, tuple]] = {c.name: {} for c in usable}
        clock = "cpu" if threads == 1 else "wall"
        for rep in range(repeats):
            shift = rep % len(usable)
            for cand in usable[shift:] + usable[:shift]:
                t_build, tree = timed(lambda cand=cand, work=work: cand.build(work.model, threads), clock)
                times[cand.name]["build"].append(t_build)
                for kind, queries in (("aligned", work.aligned), ("misaligned", work.misaligned)):
                    t_query, result = timed(
                        lambda cand=cand, tree=tree, q=queries: cand.query(tree, q, threads), clock
                    )
                    times[cand.name][kind].append(t_query)
                    if rep == 0:
                        checks[cand.name][kind] = check_exact(result, reference[kind])
        base = {k: statistics.median(v) for k, v in times["pykdtree"].items()}
        for cand in usable:
            med = {k: statistics.median(v) for k, v in times[cand.name].items()}
            worst = max(checks[cand.name].values(), key=lambda c: (c[1], c[2]))
            rows.append(
                dict(
                    workload=work.name,
                    group=work.group,
                    points=int(work.model.shape[0]),
                    dim=dim,
                    threads=threads,
                    candidate=cand.name,
                    build_ms=med["build"] * 1e3,
                    aligned_ms=med["aligned"] * 1e3,
                    misaligned_ms=med["misaligned"] * 1e3,
                    ratio_build=base["build"] / med["build"],
                    ratio_aligned=base["aligned"] / med["aligned"],
                    ratio_misaligned=base["misaligned"] / med["misaligned"],
                    mismatches=sum(c[0] for c in checks[cand.name].values()),
                    wrong=sum(c[1] for c in checks[cand.name].values()),
                    max_rel_d2_error=worst[2],
                )
            )
    return rows


def registration_mix(rows: list[dict]) -> list[dict]:
    """Per candidate and group: time of the NN work of one register call as the core does it.

    Per level: 2 builds (data and model), and 2 query passes of 2 x n queries (forward and
    backward) from a far pose plus 6 from near-aligned poses. The sum over the levels of a
    workload, and its ratio to pykdtree's.
    """
    out = []
    keys = sorted({(r["workload"].rsplit(" ", 1)[0], r["threads"]) for r in rows if r["group"] != "order"})
    for family, threads in keys:
        mine = [
            r
            for r in rows
            if r["workload"].rsplit(" ", 1)[0] == family and r["threads"] == threads and r["group"] != "order"
        ]
        total: dict[str, float] = {}
        for r in mine:
            cost = 2 * r["build_ms"] + 2 * 2 * r["misaligned_ms"] + 6 * 2 * r["aligned_ms"]
            total[r["candidate"]] = total.get(r["candidate"], 0.0) + cost
        levels = {r["points"] for r in mine}
        complete = {c: t for c, t in total.items() if sum(r["candidate"] == c for r in mine) == len(levels)}
        for cand, ms in complete.items():
            out.append(
                dict(family=family, threads=threads, candidate=cand, ms=ms, ratio=complete["pykdtree"] / ms)
            )
    return out


def kiss_icp_voxel_hash(workloads: list[Workload], threads: int, repeats: int) -> list[dict]:
    """KISS-ICP's voxel hash map: insertion, and one correspondence search + solve.

    The Python package exposes no correspondence search on its own, only
    ``_Registration._align_points_to_map``; with ``max_num_iterations=1`` it runs one voxel-hash
    data association (27 neighbouring voxels) and one Gauss-Newton step, an upper bound for
    the search itself. Which fraction of the exact nearest neighbours it can find is computed
    separately by :func:`voxel_hash_recall` (same voxel size and cap).
    """
    try:
        from kiss_icp.pybind import kiss_icp_pybind as kiss
    except ImportError:
        print("# kiss-icp: not installed; its rows are skipped", file=sys.stderr)
        return []
    rows = []
    for work in workloads:
        if work.model.shape[1] != 3:
            continue
        voxel = voxel_size(work.model)
        times: dict[str, list[float]] = {"build": [], "aligned": [], "misaligned": []}
        clock = "cpu" if threads == 1 else "wall"
        for _ in range(repeats):
            t_build, vmap = timed(lambda work=work, voxel=voxel: _kiss_map(kiss, work.model, voxel), clock)
            times["build"].append(t_build)
            reg = kiss._Registration(
                max_num_iterations=1, convergence_criterion=1e-30, max_num_threads=threads
            )
            for kind, queries in (("aligned", work.aligned), ("misaligned", work.misaligned)):
                t_query, _ = timed(
                    lambda q=queries, reg=reg, vmap=vmap, voxel=voxel: reg._align_points_to_map(
                        points=kiss._Vector3dVector(q),
                        voxel_map=vmap,
                        initial_guess=np.eye(4),
                        max_correspondance_distance=3 * voxel,
                        kernel=voxel,
                    ),
                    clock,
                )
                times[kind].append(t_query)
        med = {k: statistics.median(v) * 1e3 for k, v in times.items()}
        recall = {
            kind: voxel_hash_recall(work.model, q, voxel)
            for kind, q in (("aligned", work.aligned), ("misaligned", work.misaligned))
        }
        rows.append(
            dict(
                workload=work.name,
                threads=threads,
                voxel=voxel,
                build_ms=med["build"],
                aligned_ms=med["aligned"],
                misaligned_ms=med["misaligned"],
                recall_aligned=recall["aligned"],
                recall_misaligned=recall["misaligned"],
            )
        )
    return rows


def voxel_size(points: np.ndarray) -> float:
    """KISS-ICP's rule of thumb: voxel = max range / 100; here 1 % of the bounding-box diagonal."""
    return float(np.linalg.norm(points.max(0) - points.min(0))) / 100.0


def _kiss_map(kiss, points: np.ndarray, voxel: float):
    vmap = kiss._VoxelHashMap(voxel_size=voxel, max_distance=1e9, max_points_per_voxel=20)
    vmap._add_points(kiss._Vector3dVector(points))
    return vmap


def voxel_hash_recall(model: np.ndarray, queries: np.ndarray, voxel: float, cap: int = 20) -> dict:
    """What a KISS-ICP-style search returns (numpy re-implementation, accuracy only, not speed).

    Model points are hashed to voxels (at most ``cap`` per voxel, the first ones, as
    VoxelHashMap keeps them); a query looks at its voxel and the 26 around it and keeps the
    closest stored point if within 3 voxels (the correspondence gate). Returns the fraction of
    queries that get a correspondence at all and the fraction whose correspondence is the exact
    nearest neighbour.
    """
    keys = np.floor(model / voxel).astype(np.int64)
    off = 1 << 20

    def pack(k: np.ndarray) -> np.ndarray:
        return ((k[:, 0] + off) << 42) | ((k[:, 1] + off) << 21) | (k[:, 2] + off)

    packed = pack(keys)
    order = np.argsort(packed, kind="stable")
    sorted_keys = packed[order]
    starts = np.searchsorted(sorted_keys, sorted_keys, side="left")
    rank = np.arange(sorted_keys.size) - starts
    keep = rank < cap
    sorted_keys, order = sorted_keys[keep], order[keep]
    q_keys = np.floor(queries / voxel).astype(np.int64)
    best = np.full(queries.shape[0], np.inf)
    best_idx = np.full(queries.shape[0], -1)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                k = pack(q_keys + np.array([dx, dy, dz]))
                lo = np.searchsorted(sorted_keys, k, side="left")
                hi = np.searchsorted(sorted_keys, k, side="right")
                for j in range(cap):
                    at = lo + j
                    valid = at < hi
                    if not valid.any():
                        break
                    cand = order[np.where(valid, at, 0)]
                    d2 = ((model[cand] - queries) ** 2).sum(1)
                    better = valid & (d2 < best)
                    best = np.where(better, d2, best)
                    best_idx = np.where(better, cand, best_idx)
    found = best <= (3 * voxel) ** 2
    exact_d2, exact_idx = cKDTree(model).query(queries, k=1)
    exact = found & ((best_idx == exact_idx) | np.isclose(best, exact_d2**2, rtol=1e-9))
    return dict(found=float(found.mean()), exact=float(exact.mean()))


# ---------------------------------------------------------------------------------------------
# register() with each backend


class CandidateNeighbors(NearestNeighbors):
    """frisicp_core's NearestNeighbors contract answered by one candidate (``candidate``, set by
    :func:`neighbours_of`): ``query``, ``query_k`` and ``spacing`` as the core defines them."""

    candidate: ClassVar[Candidate]
    threads: ClassVar[int] = 1

    def __init__(self, points: np.ndarray, backend: str = "auto") -> None:
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.backend = self.candidate.name
        self._tree = self.candidate.build(self.points, self.threads)
        self._spacing = None

    def query(self, queries: np.ndarray, bound: float | None = None) -> QueryResult:
        d2, idx = self.candidate.query(self._tree, queries, self.threads)
        if bound is not None:  # the core's contract: inf beyond the bound (answered in full here)
            d2 = np.where(d2 < bound * bound, d2, np.inf)
        return d2, idx

    def query_k(self, queries: np.ndarray, k: int) -> QueryResult:
        k = min(k, self.points.shape[0])
        if k == 1:
            d2, idx = self.query(queries)
        else:
            d2, idx = self.candidate.query(self._tree, queries, self.threads, k)
        return d2.reshape(-1, k), idx.reshape(-1, k)

    def spacing(self, sample: int = 256) -> float:
        """As NearestNeighbors.spacing: the median distance to the nearest other stored point,
        over at most ``sample`` stored points spread evenly over the storage order."""
        if self._spacing is None:
            n = self.points.shape[0]
            if n < 2:
                self._spacing = 0.0
            else:
                d2, _ = self.query_k(self.points[:: max(1, n // sample)], 2)
                self._spacing = float(np.sqrt(np.median(d2[:, 1])))
        return self._spacing


def neighbours_of(candidate: Candidate) -> type[CandidateNeighbors]:
    """The NearestNeighbors class that runs ``candidate``, for :func:`neighbours_class`."""
    unanswered = sorted(
        name
        for name, value in vars(NearestNeighbors).items()
        if callable(value) and not name.startswith("_") and name not in vars(CandidateNeighbors)
    )
    if unanswered:  # inherited, they would call the core's own tree: a wrong or failing answer
        raise NotImplementedError(
            f"CandidateNeighbors does not answer NearestNeighbors.{', '.join(unanswered)}"
        )
    return type(f"{candidate.name}Neighbors", (CandidateNeighbors,), {"candidate": candidate})


def register_cases(
    sizes: Sizes, bunny: np.ndarray | None
) -> list[tuple[str, np.ndarray, np.ndarray, RegistrationConfig]]:
    rng = np.random.default_rng(11)
    truth = Similarity(1.3, rotation((0.0, 0.0, 1.0), 90.0), np.array([1.0, 2.0, 0.5]))  # node_latency.py's
    model = downsample(bumpy_surface(sizes.scan, seed=0), sizes.cap, rng)
    data = truth.inverse().apply(downsample(bumpy_surface(sizes.scan, seed=1), sizes.cap, rng))
    data += rng.normal(scale=0.002, size=data.shape)
    near = Similarity(1.3 * 1.01, truth.rotation @ rotation((1.0, 0.2, 0.1), 2.0), truth.translation + 0.02)
    # Lidar-like: a second scan 1.5 m away and yawed 3 degrees, in its own sensor frame.
    scan_pose = Similarity(1.0, rotation((0.0, 0.0, 1.0), 3.0), np.array([1.5, 0.4, 0.0]))
    scan_model = downsample(lidar_scan(sizes.scan, np.array([0.0, 0.0, 1.8]), 0.0, seed=1), sizes.cap, rng)
    scan_data = downsample(lidar_scan(sizes.scan, np.array([1.5, 0.4, 1.8]), 3.0, seed=2), sizes.cap, rng)
    scan_data = scan_pose.inverse().apply(scan_data)
    scan_near = Similarity(
        1.005, scan_pose.rotation @ rotation((0.1, 0.2, 1.0), 1.0), scan_pose.translation + 0.1
    )
    cap = f"{sizes.cap / 1000:g}k"
    cases = [
        (f"node {cap} cold", data, model, RegistrationConfig()),
        (f"node {cap} warm", data, model, RegistrationConfig(initial=near)),
        (f"lidar {cap} warm", scan_data, scan_model, RegistrationConfig(initial=scan_near)),
    ]
    if bunny is not None:
        forward = Similarity(0.5, rotation((0.3, 1.0, 0.2), 10.0), np.array([0.01, -0.02, 0.015]))
        cases.append(("bunny cold (s=0.5)", forward.apply(bunny), bunny, RegistrationConfig()))
    return cases


def bench_register(cands: list[Candidate], repeats: int, cases: list) -> list[dict]:
    exact = [c for c in cands if (c.exact or c.name == "pykdtree-f32") and not c.name.startswith("faiss")]
    variants = [(c.name, neighbours_of(c)) for c in exact]
    rows = []
    for label, data, model, config in cases:
        times: dict[str, list[float]] = {name: [] for name, _ in variants}
        results = {}
        for rep in range(repeats):
            shift = rep % len(variants)
            for name, neighbours in variants[shift:] + variants[:shift]:
                with neighbours_class(neighbours):
                    t, result = timed(
                        lambda data=data, model=model, config=config: register(data, model, config)
                    )
                times[name].append(t)
                results[name] = result
        base = statistics.median(times["pykdtree"])
        for name, _ in variants:
            med = statistics.median(times[name])
            res = results[name]
            rows.append(
                dict(
                    case=label,
                    candidate=name,
                    ms=med * 1e3,
                    ratio=base / med,
                    iterations=list(res.iterations),
                    same_result=bool(
                        np.allclose(
                            res.similarity.matrix(), results["pykdtree"].similarity.matrix(), atol=1e-9
                        )
                    ),
                )
            )
    return rows


# ---------------------------------------------------------------------------------------------
# Where register's time goes


class _Timing(NearestNeighbors):
    """The real NearestNeighbors, timing its builds and queries into class-level counters."""

    build_s: ClassVar[dict[str, float]] = {"data": 0.0, "model": 0.0}
    query_s = 0.0
    queries = 0
    builds = 0

    def __init__(self, points: np.ndarray, backend: str = "auto") -> None:
        start = time.process_time()
        super().__init__(points, backend)
        elapsed = time.process_time() - start
        # FRISICP's levels are bidirectional: each builds its data tree, then its model tree
        role = "data" if _Timing.builds % 2 == 0 else "model"
        _Timing.build_s[role] += elapsed
        _Timing.builds += 1

    def query(self, queries: np.ndarray, bound: float | None = None) -> QueryResult:
        start = time.process_time()
        result = super().query(queries, bound)
        _Timing.query_s += time.process_time() - start
        _Timing.queries += 1
        return result

    @classmethod
    def reset(cls) -> None:
        cls.build_s = {"data": 0.0, "model": 0.0}
        cls.query_s = 0.0
        cls.queries = 0
        cls.builds = 0


def bench_split(repeats: int, cases: list) -> list[dict]:
    rows = []
    for label, data, model, config in cases:
        samples = []
        for _ in range(repeats):
            _Timing.reset()
            with neighbours_class(_Timing):
                t, result = timed(lambda data=data, model=model, config=config: register(data, model, config))
            samples.append(
                dict(
                    total=t,
                    build_data=_Timing.build_s["data"],
                    build_model=_Timing.build_s["model"],
                    query=_Timing.query_s,
                    queries=_Timing.queries,
                    builds=_Timing.builds,
                    iterations=list(result.iterations),
                )
            )
        med = {
            k: statistics.median(s[k] for s in samples)
            for k in ("total", "build_data", "build_model", "query")
        }
        rows.append(
            dict(
                case=label,
                total_ms=med["total"] * 1e3,
                build_data_ms=med["build_data"] * 1e3,
                build_model_ms=med["build_model"] * 1e3,
                query_ms=med["query"] * 1e3,
                other_ms=(med["total"] - med["build_data"] - med["build_model"] - med["query"]) * 1e3,
                queries=samples[-1]["queries"],
                builds=samples[-1]["builds"],
                iterations=samples[-1]["iterations"],
            )
        )
    return rows


# ---------------------------------------------------------------------------------------------
# Down-sampling a 100k cloud


def voxel_keys_naive(points: np.ndarray, voxel: float) -> np.ndarray:
    """Voxel index of every point, the obvious way (``.min(axis=0)`` is the slow part)."""
    keys = np.floor(points / voxel).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    return (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]


def voxel_keys(points: np.ndarray, voxel: float) -> tuple[np.ndarray, int]:
    """(voxel index of every point, number of cells of the bounding grid), vectorised.

    numpy's ``a.min(axis=0)`` on an (n, 3) C-ordered array is ~25x slower than three column
    minima (its inner loop runs over the 3 columns); the cell weights are applied with one
    integer matrix-vector product. Assumes the grid has < 2^63 cells.
    """
    cells = np.floor(points * (1.0 / voxel)).astype(np.int64)
    low = np.array([cells[:, k].min() for k in range(cells.shape[1])])
    span = np.array([cells[:, k].max() for k in range(cells.shape[1])]) - low + 1
    weights = np.append(np.cumprod(span[:0:-1])[::-1], 1)  # row-major: (s1 s2, s2, 1) in 3-D
    return cells @ weights - low @ weights, int(np.prod(span))


def voxel_first(points: np.ndarray, voxel: float, naive: bool = False) -> np.ndarray:
    """One point per occupied voxel (the first in input order): keys, then np.unique (a sort)."""
    keys = voxel_keys_naive(points, voxel) if naive else voxel_keys(points, voxel)[0]
    _, first = np.unique(keys, return_index=True)
    return points[np.sort(first)]


def voxel_centroid(points: np.ndarray, voxel: float) -> np.ndarray:
    """The centroid of every occupied voxel: keys, np.unique inverse (a sort), bincount."""
    keys, _ = voxel_keys(points, voxel)
    _, inverse, counts = np.unique(keys, return_index=False, return_inverse=True, return_counts=True)
    sums = np.stack([np.bincount(inverse, weights=points[:, k], minlength=counts.size) for k in range(3)], 1)
    return sums / counts[:, None]


DENSE_GRID_MAX = 1 << 26  # cells: the owner table is 8 bytes a cell of virtual memory, touched sparsely


def dense_owners(points: np.ndarray, voxel: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Without sorting: scatter point numbers into a per-cell table, then read back for every
    point the number its voxel's cell holds (the owner), with the point numbers; None for grids
    over DENSE_GRID_MAX cells.

    With repeated indices a fancy assignment keeps the last write (numpy does so in practice, it
    does not promise it; the owner is "one of the voxel's points" either way).
    """
    keys, cells = voxel_keys(points, voxel)
    if cells > DENSE_GRID_MAX:
        return None
    order = np.arange(points.shape[0])
    owner = np.empty(cells, dtype=np.int64)
    owner[keys] = order
    return owner[keys], order


def voxel_last_dense(points: np.ndarray, voxel: float) -> np.ndarray:
    """One point per occupied voxel, its owner (:func:`dense_owners`; :func:`voxel_first` for
    larger grids)."""
    owners = dense_owners(points, voxel)
    if owners is None:
        return voxel_first(points, voxel)
    owns, order = owners
    return points[owns == order]


def voxel_centroid_dense(points: np.ndarray, voxel: float) -> np.ndarray:
    """Centroid per occupied voxel without sorting (:func:`dense_owners`, then bincount)."""
    owners = dense_owners(points, voxel)
    if owners is None:
        return voxel_centroid(points, voxel)
    owns, order = owners
    head = owns == order
    slot = np.cumsum(head) - 1  # voxel number of each owning point
    inverse = slot[owns]
    count = int(slot[-1]) + 1
    counts = np.bincount(inverse, minlength=count)
    sums = np.stack([np.bincount(inverse, weights=points[:, k], minlength=count) for k in range(3)], 1)
    return sums / counts[:, None]


VoxelMethod = Callable[[np.ndarray, float], np.ndarray]
VOXEL_METHODS: list[tuple[str, VoxelMethod]] = [
    ("keys only (fast)", lambda p, v: voxel_keys(p, v)[0]),
    ("keys only (naive, .min(axis=0))", voxel_keys_naive),
    ("first point, naive keys + np.unique(return_index)", lambda p, v: voxel_first(p, v, naive=True)),
    ("first point, fast keys + np.unique(return_index)", voxel_first),
    ("one point, dense owner table (no sort)", voxel_last_dense),
    ("centroid, np.unique(inverse) + bincount", voxel_centroid),
    ("centroid, dense owner table + bincount (no sort)", voxel_centroid_dense),
]


def library_voxel_methods() -> list[tuple[str, VoxelMethod]]:
    """small_gicp's and kiss-icp's voxel grids (C++), where installed: for reference."""
    found: list[tuple[str, VoxelMethod]] = []
    with contextlib.suppress(ImportError):
        import small_gicp

        found.append(
            (
                "centroid, small_gicp.voxelgrid_sampling (1 thread, C++)",
                lambda p, v: small_gicp.voxelgrid_sampling(p, v, 1).points(),
            )
        )
    with contextlib.suppress(ImportError):
        from kiss_icp.pybind import kiss_icp_pybind as kiss

        found.append(
            (
                "one point, kiss-icp _voxel_down_sample (C++)",
                lambda p, v: np.asarray(kiss._voxel_down_sample(kiss._Vector3dVector(p), v)),
            )
        )
    return found


def bench_downsample(repeats: int, sizes: Sizes) -> list[dict]:
    rng = np.random.default_rng(0)
    scan = lidar_scan(sizes.scan, np.array([0.0, 0.0, 1.8]), 0.0, seed=1)
    surface = bumpy_surface(sizes.scan, seed=0)
    cap = sizes.cap
    rows = []

    def add(label: str, cloud: str, action: Callable[[], np.ndarray]) -> None:
        times, out = [], None
        for _ in range(repeats):
            t, out = timed(action)
            times.append(t)
        rows.append(dict(method=label, cloud=cloud, ms=statistics.median(times) * 1e3, points=len(out)))

    scanned = f"{sizes.scan / 1000:g}k"
    for cloud, pts in ((f"lidar {scanned}", scan), (f"surface {scanned}", surface)):
        n = pts.shape[0]
        add(
            "Generator.choice(replace=False) + sort + take (sampling.downsample)",
            cloud,
            lambda p=pts: downsample(p, cap, rng),
        )
        add("Generator.choice(replace=False) only", cloud, lambda n=n: rng.choice(n, cap, replace=False))
        add(
            "Generator.permutation(n)[:k] + sort + take",
            cloud,
            lambda p=pts, n=n: p[np.sort(rng.permutation(n)[:cap])],
        )
        add(
            "random keys, argpartition + sort + take",
            cloud,
            lambda p=pts, n=n: p[np.sort(np.argpartition(rng.random(n), cap)[:cap])],
        )
        for voxel in (0.15, 0.3) if cloud.startswith("lidar") else (0.02, 0.04):
            for label, method in VOXEL_METHODS + library_voxel_methods():
                add(f"voxel {voxel}: {label}", cloud, lambda p=pts, v=voxel, m=method: m(p, v))
    return rows


# ---------------------------------------------------------------------------------------------
# Output


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for dist in (
        "numpy",
        "scipy",
        "pykdtree",
        "small_gicp",
        "pynanoflann",
        "napf",
        "scikit-learn",
        "faiss-cpu",
        "kiss-icp",
    ):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def table(title: str, header: list[str], body: list[list[object]]) -> None:
    print(f"\n## {title}\n")
    print("\n".join(markdown_table(header, body)))


def exactness(r: dict) -> str:
    if r["wrong"]:
        return f"NO: {r['wrong']} wrong, max rel. d2 error {r['max_rel_d2_error']:.1e}"
    return f"yes ({r['mismatches']} ties)" if r["mismatches"] else "yes"


def print_nn_section(threads: int, repeats: int, rows: list[dict], mix: list[dict], kiss: list[dict]) -> None:
    clock = "process CPU time" if threads == 1 else "wall time"
    table(
        f"1-NN, {threads} thread(s): medians of {repeats} ({clock}); x = pykdtree time / candidate time",
        [
            "workload",
            "candidate",
            "build ms",
            "aligned ms",
            "misaligned ms",
            "x build",
            "x aligned",
            "x misal.",
            "exact",
        ],
        [
            [
                r["workload"],
                r["candidate"],
                f"{r['build_ms']:.2f}",
                f"{r['aligned_ms']:.2f}",
                f"{r['misaligned_ms']:.2f}",
                f"{r['ratio_build']:.2f}",
                f"{r['ratio_aligned']:.2f}",
                f"{r['ratio_misaligned']:.2f}",
                exactness(r),
            ]
            for r in rows
        ],
    )
    table(
        f"NN work of one register call, {threads} thread(s): per level 2 builds + 4 misaligned "
        "+ 12 aligned n-point queries, summed over the 3 levels",
        ["family", "candidate", "ms", "x pykdtree"],
        [
            [m["family"], m["candidate"], f"{m['ms']:.1f}", f"{m['ratio']:.2f}"]
            for m in sorted(mix, key=lambda m: (m["family"], -m["ratio"]))
        ],
    )
    if kiss:
        table(
            f"KISS-ICP voxel hash map, {threads} thread(s) ({clock}): build = insert the model; "
            "query = one association + one Gauss-Newton step; matched / exact = share of queries "
            "with a correspondence / with the exact nearest neighbour",
            ["workload", "voxel", "build ms", "aligned ms", "misaligned ms", "aligned", "misaligned"],
            [
                [
                    k["workload"],
                    f"{k['voxel']:.3g}",
                    f"{k['build_ms']:.2f}",
                    f"{k['aligned_ms']:.2f}",
                    f"{k['misaligned_ms']:.2f}",
                    f"{k['recall_aligned']['found']:.1%} / {k['recall_aligned']['exact']:.1%}",
                    f"{k['recall_misaligned']['found']:.1%} / {k['recall_misaligned']['exact']:.1%}",
                ]
                for k in kiss
            ],
        )


def main(argv: list[str] | None = None) -> int:
    quick = "every section once, 1 thread, on clouds of 3,000 points (the bunny's too)"
    parser = script.parser(__file__, __doc__, quick, data=True, repeats=7, json_out=True)
    parser.add_argument("--sections", default="nn,register,split,downsample")
    parser.add_argument("--threads", default="1,2")
    args = script.parse(parser, argv)
    sections = set(args.sections.split(","))
    threads_list = [1] if args.quick else [int(t) for t in args.threads.split(",")]
    repeats = 1 if args.quick else args.repeats
    sizes = QUICK if args.quick else Sizes()
    bunny = read_bunny(args.data, sizes)
    report: dict = {"machine": f"{platform.machine()}, {os.cpu_count()} cores", "versions": versions()}
    print(f"# {report['machine']}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
    print("# " + ", ".join(f"{k} {v}" for k, v in report["versions"].items()))
    cands, missing = candidates()
    for line in missing:
        print(f"# {line}")

    if "nn" in sections:
        workloads = node_workloads(sizes) + bunny_workloads(bunny) + contour_workloads(sizes)
        report["nn"], report["mix"], report["kiss"] = [], [], []
        for threads in threads_list:
            with threadpool_limits(limits=threads):
                rows = bench_nn(cands, workloads, threads, repeats)
                kiss = kiss_icp_voxel_hash(
                    [w for w in workloads if w.group in ("node", "bunny")], threads, repeats
                )
            mix = registration_mix(rows)
            report["nn"] += rows
            report["kiss"] += kiss
            report["mix"] += mix
            print_nn_section(threads, repeats, rows, mix, kiss)

    cases = register_cases(sizes, bunny) if sections & {"register", "split"} else []
    if "register" in sections:
        with threadpool_limits(limits=1):
            rows = bench_register(cands, repeats, cases)
        report["register"] = rows
        table(
            "register() with each backend, 1 thread (process CPU time, medians); "
            "x = pykdtree time / candidate time",
            ["case", "candidate", "ms", "x pykdtree", "iterations per level", "same result as pykdtree"],
            [
                [
                    r["case"],
                    r["candidate"],
                    f"{r['ms']:.1f}",
                    f"{r['ratio']:.2f}",
                    r["iterations"],
                    r["same_result"],
                ]
                for r in rows
            ],
        )

    if "split" in sections:
        with threadpool_limits(limits=1):
            rows = bench_split(repeats, cases)
        report["split"] = rows
        table(
            "Where register's time goes (frisicp_core's NearestNeighbors, 1 thread, "
            "process CPU time, medians)",
            [
                "case",
                "total ms",
                "data trees ms",
                "model trees ms",
                "queries ms",
                "rest ms",
                "builds",
                "queries",
                "iterations",
            ],
            [
                [
                    r["case"],
                    f"{r['total_ms']:.1f}",
                    f"{r['build_data_ms']:.1f}",
                    f"{r['build_model_ms']:.1f}",
                    f"{r['query_ms']:.1f}",
                    f"{r['other_ms']:.1f}",
                    r["builds"],
                    r["queries"],
                    r["iterations"],
                ]
                for r in rows
            ],
        )

    if "downsample" in sections:
        with threadpool_limits(limits=1):
            rows = bench_downsample(1 if args.quick else max(repeats, 9), sizes)
        report["downsample"] = rows
        table(
            f"Down-sampling a {sizes.scan // 1000}k-point cloud, 1 thread (process CPU time, medians)",
            ["cloud", "method", "ms", "points out"],
            [[r["cloud"], r["method"], f"{r['ms']:.2f}", r["points"]] for r in rows],
        )

    script.write_json(args.json, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
