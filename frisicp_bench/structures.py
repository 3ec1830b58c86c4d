"""Synthetic man-made scenes whose structure repeats: what a robot meets indoors and what makes a
registration ambiguous.

Every scene is made of planar patches sampled uniformly by area (``density`` points per square
metre), in metres:

- *corridor*: 20 m long, 2 m wide, 2.5 m high, open at both ends (slides along itself);
- *hall*: an empty 6 x 4 x 2.5 m room (a half turn about its vertical axis maps it onto itself);
- *tables*: the hall with four tables placed symmetrically (the same half turn);
- *stairs*: ten steps against a wall;
- *shelves*: an 8 m rack of eight bays and five shelves (half turns and a 1 m period);
- *triangle* and *pavilion*: three and six pillars on a circle over a round floor (turns of a
  third and a sixth of a turn);
- *corner*: three 5 m walls meeting at a corner (the same at every scale about it).

The exact symmetries are the point: a crop of such a scene fits it as well at its twin's place,
so the honest verdict is "ambiguous" (or "not determined"), whichever pose is returned.

One kind has none (:data:`ROOMS`): *furnished*, a room of random size (4-8 x 3-6 x 2.4-3 m,
floor, walls and ceiling) with five to nine boxes of furniture (0.4-2 m wide, 0.4-1.2 m deep,
0.4-2 m high) at random places and headings, a new layout for every case: a room the method was
never looked at, where a crop that holds furniture determines its pose and a right answer can be
reliable.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable

import numpy as np

from frisicp_core import FloatArray, axis_angle_rotation, downsample

from .metrics import model_size
from .scenes import NOISE, SceneCase, box_crop, protocol_similarity, resampled

KINDS = ("corridor", "hall", "tables", "stairs", "shelves", "triangle", "pavilion", "corner")
ROOMS = ("furnished",)
DENSITY = 1500.0
_HALL = (6.0, 4.0, 2.5)


def rectangle(
    origin: tuple[float, ...],
    u: tuple[float, ...],
    v: tuple[float, ...],
    density: float,
    rng: np.random.Generator,
) -> FloatArray:
    """Points uniform on the parallelogram origin + a u + b v, a and b in [0, 1]."""
    o, du, dv = (np.asarray(x, dtype=np.float64) for x in (origin, u, v))
    count = max(1, int(np.linalg.norm(np.cross(du, dv)) * density))
    a, b = rng.random((2, count))
    points: FloatArray = o + a[:, None] * du + b[:, None] * dv
    return points


def box_surface(
    low: tuple[float, ...],
    high: tuple[float, ...],
    density: float,
    rng: np.random.Generator,
    *,
    bottom: bool = True,
) -> FloatArray:
    """The faces of the axis-aligned box [low, high] (without its bottom face if not ``bottom``)."""
    lo, size = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64) - low
    ex, ey, ez = (tuple(edge) for edge in np.diag(size))
    at = tuple(lo)

    def shifted(edge: tuple[float, ...]) -> tuple[float, ...]:
        return tuple(lo + edge)

    faces = [
        rectangle(shifted(ez), ex, ey, density, rng),
        rectangle(at, ex, ez, density, rng),
        rectangle(shifted(ey), ex, ez, density, rng),
        rectangle(at, ey, ez, density, rng),
        rectangle(shifted(ex), ey, ez, density, rng),
    ]
    if bottom:
        faces.append(rectangle(at, ex, ey, density, rng))
    return np.concatenate(faces)


def disc(radius: float, density: float, rng: np.random.Generator) -> FloatArray:
    """Points uniform on a disc of ``radius`` in the plane z = 0 about the origin."""
    count = int(np.pi * radius**2 * density)
    r, angle = radius * np.sqrt(rng.random(count)), 2.0 * np.pi * rng.random(count)
    return np.stack([r * np.cos(angle), r * np.sin(angle), np.zeros(count)], axis=1)


def corridor(density: float, rng: np.random.Generator) -> FloatArray:
    length, width, height = 20.0, 2.0, 2.5
    along = (length, 0.0, 0.0)
    return np.concatenate(
        [
            rectangle((0, 0, 0), along, (0, width, 0), density, rng),
            rectangle((0, 0, height), along, (0, width, 0), density, rng),
            rectangle((0, 0, 0), along, (0, 0, height), density, rng),
            rectangle((0, width, 0), along, (0, 0, height), density, rng),
        ]
    )


def hall(density: float, rng: np.random.Generator) -> FloatArray:
    return box_surface((0.0, 0.0, 0.0), _HALL, density, rng)


def tables(density: float, rng: np.random.Generator) -> FloatArray:
    furniture = [
        box_surface((x, y, 0.0), (x + 1.0, y + 0.6, 0.75), density, rng, bottom=False)
        for x in (1.0, 4.0)
        for y in (0.8, 2.6)
    ]
    return np.concatenate([hall(density, rng), *furniture])


def stairs(density: float, rng: np.random.Generator) -> FloatArray:
    steps = []
    for k in range(10):
        steps.append(rectangle((0, 0.3 * k, 0.2 * k), (1.5, 0, 0), (0, 0, 0.2), density, rng))
        steps.append(rectangle((0, 0.3 * k, 0.2 * (k + 1)), (1.5, 0, 0), (0, 0.3, 0), density, rng))
    return np.concatenate([*steps, rectangle((0, 0, 0), (0, 3.0, 0), (0, 0, 2.5), density, rng)])


def shelves(density: float, rng: np.random.Generator) -> FloatArray:
    parts = [rectangle((0, 0, 0), (8.0, 0, 0), (0, 0, 2.0), density, rng)]
    parts += [rectangle((x, 0, 0), (0, 0.4, 0), (0, 0, 2.0), density, rng) for x in np.arange(9.0)]
    parts += [rectangle((0, 0, z), (8.0, 0, 0), (0, 0.4, 0), density, rng) for z in (0.0, 0.5, 1.0, 1.5, 2.0)]
    return np.concatenate(parts)


def pillars(count: int) -> Callable[[float, np.random.Generator], FloatArray]:
    def scene(density: float, rng: np.random.Generator) -> FloatArray:
        parts = [disc(5.0, density, rng)]
        for k in range(count):
            angle = 2.0 * np.pi * k / count
            x, y = 3.0 * np.cos(angle), 3.0 * np.sin(angle)
            parts.append(
                box_surface((x - 0.3, y - 0.3, 0.0), (x + 0.3, y + 0.3, 2.5), density, rng, bottom=False)
            )
        return np.concatenate(parts)

    return scene


def corner(density: float, rng: np.random.Generator) -> FloatArray:
    return np.concatenate(
        [
            rectangle((0, 0, 0), (5, 0, 0), (0, 5, 0), density, rng),
            rectangle((0, 0, 0), (5, 0, 0), (0, 0, 5), density, rng),
            rectangle((0, 0, 0), (0, 5, 0), (0, 0, 5), density, rng),
        ]
    )


SCENES: dict[str, Callable[[float, np.random.Generator], FloatArray]] = {
    "corridor": corridor,
    "hall": hall,
    "tables": tables,
    "stairs": stairs,
    "shelves": shelves,
    "triangle": pillars(3),
    "pavilion": pillars(6),
    "corner": corner,
}


def furnished_room(layout: np.random.Generator) -> Callable[[float, np.random.Generator], FloatArray]:
    """A sampler of one furnished room (module doc) whose layout ``layout`` draws now: every
    sampling of it shows the same room."""
    size = (layout.uniform(4.0, 8.0), layout.uniform(3.0, 6.0), layout.uniform(2.4, 3.0))
    pieces = []
    for _ in range(int(layout.integers(5, 10))):
        width, depth, height = layout.uniform(0.4, 2.0), layout.uniform(0.4, 1.2), layout.uniform(0.4, 2.0)
        heading = layout.uniform(0.0, np.pi)
        # Inside the walls whatever the heading: the centre keeps half the diagonal from them.
        reach = 0.5 * np.hypot(width, depth)
        centre = (layout.uniform(reach, size[0] - reach), layout.uniform(reach, size[1] - reach))
        pieces.append(((width, depth, height), heading, centre))

    def scene(density: float, rng: np.random.Generator) -> FloatArray:
        parts = [box_surface((0.0, 0.0, 0.0), size, density, rng)]
        for (width, depth, height), heading, (x, y) in pieces:
            box = box_surface(
                (-width / 2, -depth / 2, 0.0), (width / 2, depth / 2, height), density, rng, bottom=False
            )
            turn = axis_angle_rotation((0.0, 0.0, 1.0), heading)
            parts.append(box @ turn.T + np.array([x, y, 0.0]))
        return np.concatenate(parts)

    return scene


def structured_crop_case(
    kind: str, share: float, scale: float, rng: np.random.Generator, *, reverse: bool = False
) -> SceneCase:
    """A crop of ``share`` of one sampling of the scene ``kind`` onto another sampling of it
    (``reverse``: the scene onto the crop): independent samplings, as two sensors' or two
    visits' are, not a subset of one (a copy's shared samples make the true pose fit better
    than its exact twins). The crop is a cube about a random point (30-100 % of its points
    kept); both get Gaussian noise of :data:`~frisicp_bench.scenes.NOISE` of the scene's
    diagonal; the data are moved by ``frisicp bench``'s protocol (``scale``, a turn of up to 30
    degrees, a shift of a tenth of the model's size)."""
    # A furnished room's layout is drawn once: both samplings show the same room.
    sample = furnished_room(rng) if kind in ROOMS else SCENES[kind]
    first, second = sample(DENSITY, rng), sample(DENSITY, rng)
    noise = NOISE * model_size(first)
    crop = resampled(box_crop(second, share, rng), rng.uniform(0.3, 1.0), noise, rng)
    whole = resampled(first, 1.0, noise, rng)
    data, model = (whole, crop) if reverse else (crop, whole)
    moved = protocol_similarity(model, scale, 30.0, rng)
    suite = "scene onto crop" if reverse else "crop onto scene"
    name = f"{kind} {share:.0%} s={scale:.3g}"
    return SceneCase(name, suite, moved.apply(data), model, moved.inverse())


# benchmarks/structured_scenes.py's cases: each a scale of these, registered both ways.
SCALES = (0.5, 0.8, 1.3, 2.0, 3.0)
DIRECTIONS = ("crop onto scene", "scene onto crop")


def seeded_case(
    kind: str, share: float, direction: str, repeat: int, draw: int, cap: int
) -> tuple[SceneCase, FloatArray, FloatArray]:
    """benchmarks/structured_scenes.py's case ``kind``/``share``/``direction``/``repeat`` of
    ``--draw`` ``draw``: :func:`structured_crop_case` at a scale of :data:`SCALES`, all drawn
    from a generator seeded by the key, and its data and model capped at ``cap`` random points
    each (the same clouds in the script, in tests and in one-off diagnostics)."""
    salt = f"{kind}/{share}/{direction}/{repeat}" + (f"/draw {draw}" if draw else "")
    rng = np.random.default_rng(zlib.crc32(salt.encode()))
    case = structured_crop_case(
        kind, share, float(rng.choice(SCALES)), rng, reverse=direction == "scene onto crop"
    )
    return case, downsample(case.data, cap, rng), downsample(case.model, cap, rng)


def structured_scene(kind: str, rng: np.random.Generator, density: float = DENSITY) -> FloatArray:
    """The scene ``kind`` (one of :data:`KINDS` or :data:`ROOMS`, module doc), sampled with
    ``rng`` (a furnished room's layout drawn from it first)."""
    sample = furnished_room(rng) if kind in ROOMS else SCENES[kind]
    return sample(density, rng)
