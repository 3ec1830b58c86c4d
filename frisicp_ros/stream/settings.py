"""Every option of ``register_node``, ``frisicp bag`` and ``frisicp register``, defined once.

:data:`OPTIONS` is the table: one :class:`Option` per setting with its name, type, default, range
or choices, description and the surfaces it appears on. Generated from it:

- the node's parameter declarations and descriptors (``frisicp_ros.node.parameters``);
- ``config/frisicp.yaml`` (:func:`render_yaml`, written by ``make config``; a test keeps the file
  equal to it);
- the command-line options of ``frisicp bag`` and ``frisicp register``
  (``frisicp_ros.cli.options``).

Algorithm rows name a field of :class:`~frisicp_core.RegistrationConfig` (``core``; dotted for
the fields of ``criteria`` and ``tolerance``) and take their type, default and enum choices from
``RegistrationConfig()``, so adding or changing a core option is one row here. One exception:
``budget_seconds`` is a stream option with a stream default (5 s; the core's is unbounded, for
whole clouds). ROS parameters have no null: a core ``None``
is written as the type's zero (0, 0.0 or ""), and the row's ``zero_means`` says what that stands
for ("off", "automatic"). Values are always in that parameter form (bool, int, float, str);
:func:`settings_from` validates them and builds the typed :class:`PipelineSettings`.
"""

from __future__ import annotations

import dataclasses
import enum
import textwrap
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from frisicp_core import BACKENDS, RegistrationConfig
from frisicp_ros.stream.motion import MOTION_MODELS, MotionModel
from frisicp_ros.stream.pairing import PAIRING_MODES, PairingMode
from frisicp_ros.stream.pointcloud2 import VOXEL_MODES, VoxelMode

Value = bool | int | float | str


class Surface(enum.Flag):
    """Where an option can be set."""

    NODE = enum.auto()  # register_node parameters, config/frisicp.yaml
    BAG = enum.auto()  # frisicp bag
    REGISTER = enum.auto()  # frisicp register


STREAM = Surface.NODE | Surface.BAG  # everything that processes a stream of clouds
EVERYWHERE = Surface.NODE | Surface.BAG | Surface.REGISTER


class Group(str, enum.Enum):
    """Sections of the YAML file and of ``--help``, in this order."""

    NODE = "node"  # the live node only: subscriptions, diagnostics
    REPLAY = "bag replay"  # the node reading its clouds from a bag
    STREAM = "stream"  # pairing and conversion of clouds, node and bag mode
    ALGORITHM = "algorithm"  # frisicp_core.RegistrationConfig


@dataclass(frozen=True)
class Rule:
    """A check beyond type, range and choices: ``text`` is what it demands (said in the error, the
    node's parameter descriptor, the YAML comment and ``--help``), ``holds`` decides."""

    text: str
    holds: Callable[[Any], bool]


@dataclass(frozen=True)
class Option:
    """One row of the table. Build rows with :func:`option` or :func:`core_option`."""

    name: str
    kind: type  # bool, int, float or str
    default: Value
    description: str
    surfaces: Surface
    group: Group
    choices: tuple[str, ...] | None = None
    bounds: tuple[float, float] | None = None  # inclusive; ints and floats
    read_only: bool = False  # node: set at start-up only (subscriptions are made once)
    core: str | None = None  # RegistrationConfig field ("criteria.max_iterations", "tolerance.scale" nested)
    zero_means: str | None = None  # what 0 / 0.0 / "" stands for: the core's None
    flags: tuple[str, ...] = ()  # command-line spellings; default --name-with-dashes
    needs: tuple[str, Value] | None = None  # CLI: only meaningful with that option at that value
    rule: Rule | None = None

    @property
    def cli_flags(self) -> tuple[str, ...]:
        return self.flags or ("--" + self.name.replace("_", "-"),)

    def check(self, value: object) -> Value:
        """``value`` as this option's type, or ValueError naming the option and the reason."""
        if self.kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, bool | int | float | str) or type(value) is not self.kind:
            raise ValueError(f"{self.name} must be a {self.kind.__name__}, got {value!r}")
        if self.choices is not None and value not in self.choices:
            raise ValueError(f"{self.name} must be one of {', '.join(self.choices)}, got {value!r}")
        if self.bounds is not None and isinstance(value, int | float):
            low, high = self.bounds
            if not low <= value <= high:
                raise ValueError(f"{self.name} must be in [{_number(low)}, {_number(high)}], got {value!r}")
        if self.rule is not None and not self.rule.holds(value):
            raise ValueError(f"{self.name} must be {self.rule.text}, got {_shown(value)}")
        return value

    def to_core(self, value: Value) -> object:
        """The RegistrationConfig value of a parameter value (zero -> None, str -> enum)."""
        if self.zero_means is not None and value == self.kind():
            return None
        field_type = type(_core_default(self.core)) if self.core else None
        if field_type is not None and issubclass(field_type, enum.Enum):
            return field_type(value)
        return value


def option(
    name: str,
    default: Value,
    description: str,
    surfaces: Surface,
    group: Group,
    **details: Any,
) -> Option:
    """A row whose default is written here (options the core does not have)."""
    return Option(name, type(default), default, description, surfaces, group, **details)


def node_option(name: str, default: Value, description: str, **details: Any) -> Option:
    """A parameter of the live node only, set at start-up (subscriptions are made once)."""
    return option(name, default, description, Surface.NODE, Group.NODE, read_only=True, **details)


def replay_option(name: str, default: Value, description: str, **details: Any) -> Option:
    """A parameter of the node's bag replay (``frisicp_ros.node.replay``), set at start-up."""
    return option(name, default, description, Surface.NODE, Group.REPLAY, read_only=True, **details)


def stream_option(name: str, default: Value, description: str, **details: Any) -> Option:
    """An option of every stream of clouds: the node and ``frisicp bag``."""
    return option(name, default, description, STREAM, Group.STREAM, **details)


def core_option(
    name: str,
    description: str,
    core: str | None = None,
    surfaces: Surface = EVERYWHERE,
    kind: type | None = None,
    default: Value | None = None,
    **details: Any,
) -> Option:
    """A row backed by a RegistrationConfig field (``core``, default: ``name``).

    Type, default and enum choices come from ``RegistrationConfig()``. A field whose default is
    None needs ``kind`` and ``zero_means``: the parameter's zero stands for None. ``default``
    replaces the core's for a stream-only row (``budget_seconds``: a stream must keep up, while
    a library call runs to its end).
    """
    path = core or name
    if default is not None and surfaces & Surface.REGISTER:
        raise TypeError(f"{name}: frisicp register takes the core's defaults; a row's own is for streams")
    default = _core_default(path) if default is None else default
    choices = details.pop("choices", None)
    if isinstance(default, enum.Enum):
        choices = choices or tuple(str(member.value) for member in type(default))
        default = default.value
    if default is None:
        if kind is None or "zero_means" not in details:
            raise TypeError(f"{name}: the core default is None; give kind= and zero_means=")
        default = kind()
    kind = kind or type(default)
    return Option(
        name,
        kind,
        kind(default),
        description,
        surfaces,
        Group.ALGORITHM,
        choices=choices,
        core=path,
        **details,
    )


def _core_default(path: str | None) -> Any:
    value: Any = RegistrationConfig()
    for part in (path or "").split("."):
        value = getattr(value, part)
    return value


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(value)


def _shown(value: Value) -> str:
    """A value for an error message: a 5,000-character string must not become the message."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:50]}... ({len(str(value))} characters)"


# Voxels finer than this (in the clouds' units; a micrometre in metres) keep every point of any
# real cloud and only cost a sort (70 ms per 100k points); 1e-300 made the grid overflow float64.
SMALLEST_VOXEL = 1e-6
VOXEL_RULE = Rule(f"0 (off) or at least {SMALLEST_VOXEL:g}", lambda size: size == 0 or size >= SMALLEST_VOXEL)
# A tf2 frame id: no length limit there, but a 5,000-character one can only be a mistake (after
# it every pair was rejected as a frame mismatch); spaces and control characters likewise.
LONGEST_FRAME = 255
FRAME_RULE = Rule(
    f"a frame id of at most {LONGEST_FRAME} printable characters without spaces, or empty",
    lambda frame: len(frame) <= LONGEST_FRAME and frame.isprintable() and not any(c.isspace() for c in frame),
)


# The registration budget of the node and frisicp bag (the core's default is unbounded). A cold
# search of a partly overlapping scene (the global search, probes, polish) took 1-8 s on the
# loaded 2-core test machine; a budget below that would end every first registration unreliable,
# and the stream would never reach tracking (~70 ms a scan).
STREAM_BUDGET_SECONDS = 15.0


class SubscriptionQos(str, enum.Enum):
    """The QoS choices of the node's cloud subscriptions (``model_qos``, ``data_qos``)."""

    SENSOR_DATA = "sensor_data"  # best effort, depth 5
    RELIABLE = "reliable"  # depth 5
    TRANSIENT_LOCAL = "transient_local"  # reliable, transient local, depth 1: a latched map


MODEL_QOS_CHOICES: tuple[str, ...] = tuple(qos.value for qos in SubscriptionQos)
DATA_QOS_CHOICES: tuple[str, ...] = (SubscriptionQos.SENSOR_DATA.value, SubscriptionQos.RELIABLE.value)

OPTIONS: tuple[Option, ...] = (
    # --- the live node -------------------------------------------------------------------------
    node_option(
        "model_qos",
        SubscriptionQos.SENSOR_DATA.value,
        "QoS of the model subscription: sensor_data (best effort, depth 5), reliable (depth 5), or "
        "transient_local (reliable, transient local, depth 1: a latched map)",
        choices=MODEL_QOS_CHOICES,
    ),
    node_option(
        "data_qos",
        SubscriptionQos.SENSOR_DATA.value,
        "QoS of the data subscription: sensor_data or reliable (depth 5)",
        choices=DATA_QOS_CHOICES,
    ),
    node_option("diagnostics_period", 1.0, "seconds between /diagnostics messages", bounds=(0.1, 60.0)),
    node_option(
        "stale_after",
        3.0,
        '/diagnostics says WARN "no data for N s" when no data cloud has arrived for this many'
        " seconds (after the first one)",
        bounds=(0.1, 3600.0),
    ),
    node_option(
        "publish_tf",
        False,
        "also publish each reliable result on /tf (tf2_msgs/TFMessage): model frame -> tf_child_frame,"
        " the data frame scaled by s; needs tf2_msgs (a ROS installation: not on PyPI)",
    ),
    option(
        "initial_scale",
        0.0,
        "scale s of the initial guesses on ~/initial_guess (model = s R data + t), taken as known"
        " within 1 %; 0 = unknown (searched)",
        Surface.NODE,
        Group.NODE,
        bounds=(0.0, 1e9),
        zero_means="unknown",
    ),
    # --- the node replaying a bag (frisicp_ros.node.replay) ------------------------------------
    replay_option(
        "bag",
        "",
        "replay this bag (rosbag2 folder, .db3/.mcap file or ROS 1 .bag) instead of subscribing;"
        " its topics follow the remappings of model and data; empty = live",
    ),
    replay_option(
        "bag_rate",
        1.0,
        "replay speed: 1 = the recorded rate, 2 = twice as fast, 0 = as fast as possible",
        bounds=(0.0, 1000.0),
    ),
    replay_option(
        "bag_delay",
        1.0,
        "seconds to wait before the first pair, so subscribers can discover the node",
        bounds=(0.0, 3600.0),
    ),
    replay_option(
        "bag_wait_for_subscribers",
        0,
        "before that delay, wait until ~/transform has this many subscribers",
        bounds=(0, 1000),
    ),
    replay_option(
        "bag_exit_on_end",
        True,
        "shut the node down when the bag is done (after subscribers acknowledged the outputs);"
        " false = stay up, idle",
    ),
    # --- the stream: node and bag mode ---------------------------------------------------------
    stream_option(
        "pairing",
        PairingMode.LATEST_MODEL.value,
        "latest_model: each data cloud against the newest model before it (map-to-scan);"
        " synchronized: model and data by header stamp within sync_tolerance (two sensors)",
        choices=PAIRING_MODES,
    ),
    stream_option(
        "sync_tolerance",
        0.05,
        "largest header stamp difference (s) of a synchronized pair",
        bounds=(0.0, 10.0),
        needs=("pairing", PairingMode.SYNCHRONIZED.value),
    ),
    stream_option("dims", 3, "3: register x y z; 2: x y only (planar scans)", bounds=(2, 3)),
    stream_option(
        "max_points",
        10000,
        "cap on points per data cloud (a random subset above it) to bound latency: a tracked 10000-point"
        " scan registers in ~30-70 ms on one core, within a 10 Hz sensor's period (a cold search"
        " of a partly overlapping scene takes seconds); 0 = no cap. The model"
        " is never capped (prepared once per message at full resolution)",
        bounds=(0, 100_000_000),
    ),
    stream_option(
        "voxel_size",
        0.0,
        "edge of a voxel grid (in the clouds' units, m for most sensors) applied to both clouds"
        " (to data clouds before max_points): one point per occupied voxel is kept (voxel_mode); 0 = off",
        bounds=(0.0, 1e9),
        rule=VOXEL_RULE,
    ),
    stream_option(
        "voxel_mode",
        VoxelMode.FIRST.value,
        "what the voxel grid keeps of each occupied voxel: first (its first point, a measured one)"
        " or centroid (the mean of its points: smooths the terraces of a depth camera's quantised"
        " depth, on which two nearby frames can lock; voxel_size a depth step; the node and"
        " frisicp bag say when the data need it, README 'Depth-sensor noise')",
        choices=VOXEL_MODES,
    ),
    stream_option(
        "warm_start", True, "start each registration from the previous converged estimate (tracking)"
    ),
    stream_option(
        "motion_model",
        MotionModel.CONSTANT_VELOCITY.value,
        "warm start of a moving sensor: constant_velocity (the last result moved on by the sensor's"
        " recent velocity for the stamp gap; needs increasing stamps) or none (the last result)",
        choices=MOTION_MODELS,
    ),
    stream_option(
        "tf_child_frame",
        "",
        "child frame of the /tf transforms (node with publish_tf, frisicp bag's result bag): the data"
        " frame scaled by s; empty = '<data frame>_scaled'",
        rule=FRAME_RULE,
    ),
    stream_option(
        "model_frame", "", "expected frame id of the model clouds; empty = accept any", rule=FRAME_RULE
    ),
    stream_option(
        "data_frame", "", "expected frame id of the data clouds; empty = accept any", rule=FRAME_RULE
    ),
    stream_option(
        "publish_aligned",
        True,
        "the data cloud mapped into the model frame: the node publishes ~/aligned while it has"
        " subscribers, frisicp bag writes it into the result bag",
        flags=("--aligned",),
    ),
    # --- the algorithm: frisicp_core.RegistrationConfig ----------------------------------------
    core_option(
        "method",
        "algorithm: frisicp (bidirectional, free scale), icp (s = 1), scale-icp (Zinsser), bounded-icp (Du)",
    ),
    core_option("levels", "sparse-to-dense levels", bounds=(1, 10)),
    core_option("coarsest_points", "points on the coarsest level", bounds=(10, 10_000_000)),
    core_option(
        "max_iterations", "iteration cap per level", core="criteria.max_iterations", bounds=(1, 100_000)
    ),
    core_option(
        "relative_motion",
        "convergence: motion between iterations relative to the model's RMS radius (finest level)",
        core="criteria.relative_motion",
        bounds=(0.0, 1.0),
    ),
    core_option(
        "relative_rmse",
        "convergence: relative change of the error between iterations",
        core="criteria.relative_rmse",
        bounds=(0.0, 1.0),
    ),
    core_option(
        "coarse_relative_motion",
        "convergence motion threshold on the coarse levels",
        core="criteria.coarse_relative_motion",
        bounds=(0.0, 1.0),
    ),
    core_option(
        "noise_floor",
        "convergence: also stop once a step is smaller than the estimate's standard error"
        " (RMS residual / sqrt(pairs)); false = iterate down to relative_motion",
        core="criteria.noise_floor",
    ),
    core_option(
        "overlap",
        "share (0, 1] of each cloud's points that have a counterpart in the other: only that share"
        " of the closest correspondences is used (trimming); 1 = all; 0 = estimated from the data,"
        " separately per direction and iteration (scan in map, map in scan, two scans)",
        kind=float,
        zero_means="estimated",
        bounds=(0.0, 1.0),
    ),
    core_option(
        "symmetric",
        "symmetric scale: errors measured half-way between the two frames, so data onto model and"
        " model onto data are the same problem; false = the paper's scale (errors in the model frame)",
    ),
    core_option(
        "max_distance",
        "drop correspondences farther than this many times the median distance; 0 = keep all",
        kind=float,
        zero_means="off",
        bounds=(0.0, 1e6),
    ),
    core_option(
        "dense_targets",
        "levels above the coarsest pair subsets of points with the full other cloud (exact"
        " neighbours: every level estimates the same pose); false = both thinned (the paper)",
    ),
    core_option(
        "initialization",
        "cold start: identity, moments, principal-axes, or search (principal axes plus the data in"
        " place at several scales: partial overlap in roughly aligned frames)",
        flags=("--init", "--initialization"),
    ),
    core_option(
        "acceleration", "Anderson acceleration of the iterations (kept only when it lowers the error)"
    ),
    core_option(
        "tolerance_rotation_deg",
        "reliable only when 3 sigma of the rotation lie within this many degrees; two poses farther"
        " apart are distinct answers (an ambiguity when both fit about as well)",
        core="tolerance.rotation_deg",
        bounds=(1e-6, 180.0),
    ),
    core_option(
        "tolerance_scale",
        "reliable only when 3 sigma of the scale lie within this share of it (0.01 = 1 %)",
        core="tolerance.scale",
        bounds=(1e-6, 1.0),
    ),
    core_option(
        "tolerance_translation",
        "reliable only when 3 sigma of the translation (where the data's centroid lands) lie within"
        " this share of the model's bounding-box diagonal",
        core="tolerance.translation",
        bounds=(1e-6, 1.0),
    ),
    core_option(
        "probe",
        "probe the answer for competing poses (ICP restarted from poses turned, scaled and shifted"
        " around it, and from its twins turned half a turn about the clouds' principal axes; a"
        " reliable answer also polished again 1.5 tolerances off in scale and turn): an answer"
        " another pose fits about as well is not reliable, a clearly better one replaces it;"
        " false = faster, ambiguity unchecked",
    ),
    core_option(
        "polish",
        "finish with point-to-plane Gauss-Newton steps on both directions and estimate the"
        " covariance (the pose's covariance, the uncertainty of results, the tolerance check);"
        " false = point-to-point ICP to the end, no covariance",
    ),
    core_option(
        "average_depth_steps",
        "where both clouds come in a depth camera's coarse depth steps about their frames' origins,"
        " register their averages over voxels a step wide (not again where voxel_mode: centroid"
        " averages them already): two frames of such a camera otherwise lock terrace onto terrace,"
        " a wrong pose that looks reliable; false = registered as read",
    ),
    core_option("seed", "seed of the random down-sampling", bounds=(0, 2**31 - 1)),
    core_option("backend", "KD-tree library (auto: pykdtree when installed)", choices=BACKENDS),
    core_option(
        "budget_seconds",
        "wall-clock seconds one registration may take: past it the iterations stop and the result"
        ' is unreliable ("budget exceeded"), so no cloud holds the worker for long (tracking a'
        " 10000-point scan takes ~70 ms, a cold search of a partly overlapping scene 1-8 s); 0 = unbounded",
        kind=float,
        zero_means="unbounded",
        bounds=(0.0, 86400.0),
        surfaces=STREAM,
        default=STREAM_BUDGET_SECONDS,
    ),
    core_option(
        "drop_nonfinite",
        "drop NaN/Inf points instead of failing (clouds in the node and bag mode always drop them)",
        surfaces=Surface.REGISTER,
    ),
)
OPTIONS_BY_NAME: dict[str, Option] = {o.name: o for o in OPTIONS}
# RegistrationConfig fields that are no option: the pipeline sets the warm start itself, and an
# initial guess comes as a pose (~/initial_guess, --initial; frisicp_ros.stream.guess).
NOT_OPTIONS = ("initial", "guess")


def options_for(surface: Surface, groups: Iterable[Group] = tuple(Group)) -> tuple[Option, ...]:
    wanted = set(groups)
    return tuple(o for o in OPTIONS if surface & o.surfaces and o.group in wanted)


def defaults(surface: Surface = Surface.NODE) -> dict[str, Value]:
    """Every default of a surface's options, by name (for NODE: the YAML file's content)."""
    return {o.name: o.default for o in options_for(surface)}


def checked(values: Mapping[str, object]) -> dict[str, Value]:
    """Values converted to their options' types; ValueError names an unknown or invalid one."""
    result = {}
    for name, value in values.items():
        if name not in OPTIONS_BY_NAME:
            raise ValueError(f"unknown option {name!r}")
        result[name] = OPTIONS_BY_NAME[name].check(value)
    return result


def registration_config(
    values: Mapping[str, object], base: RegistrationConfig | None = None
) -> RegistrationConfig:
    """``base`` (default ``RegistrationConfig()``) with the algorithm options among ``values``.

    Values are checked against the table first; then the core validates its own options (a bad
    combination raises its ValueError).
    """
    base = base or RegistrationConfig()
    top: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for name, value in checked(values).items():
        row = OPTIONS_BY_NAME[name]
        if row.core is None:
            continue
        owner, _, field_name = row.core.rpartition(".")
        if owner:
            nested.setdefault(owner, {})[field_name] = row.to_core(value)
        else:
            top[field_name] = row.to_core(value)
    for owner, changes in nested.items():
        top[owner] = dataclasses.replace(getattr(base, owner), **changes)
    return dataclasses.replace(base, **top)


def algorithm_values(config: RegistrationConfig, surface: Surface = STREAM) -> dict[str, Value]:
    """A configuration's algorithm options in parameter form (None -> zero, enum -> its value)."""
    values: dict[str, Value] = {}
    for row in options_for(surface, [Group.ALGORITHM]):
        value: Any = config
        for part in (row.core or row.name).split("."):
            value = getattr(value, part)
        if isinstance(value, enum.Enum):
            value = value.value
        values[row.name] = row.kind() if value is None else row.kind(value)
    return values


@dataclass(frozen=True)
class PipelineSettings:
    """What a :class:`~frisicp_ros.stream.pipeline.RegistrationPipeline` runs with: the stream
    options of the table and the core's configuration. Build it with :func:`settings_from` (table
    defaults for what is not given) or :meth:`create`; construction validates every field.
    """

    dims: int
    max_points: int
    voxel_size: float
    voxel_mode: str
    warm_start: bool
    motion_model: str
    pairing: str
    sync_tolerance: float
    model_frame: str
    data_frame: str
    publish_aligned: bool
    tf_child_frame: str
    registration: RegistrationConfig

    def __post_init__(self) -> None:
        for name in _STREAM_FIELDS:
            OPTIONS_BY_NAME[name].check(getattr(self, name))

    @classmethod
    def create(cls, **values: Value) -> PipelineSettings:
        """Settings from option values by name; everything else at its table default."""
        return settings_from(values)

    def values(self) -> dict[str, Value]:
        """Every stream and algorithm option in parameter form (what ``create`` takes back)."""
        stream: dict[str, Value] = {name: getattr(self, name) for name in _STREAM_FIELDS}
        return {**stream, **algorithm_values(self.registration)}

    def updated(self, **changes: Value) -> PipelineSettings:
        """A validated copy with some options changed (ValueError names the bad one)."""
        return settings_from({**self.values(), **changes})


_STREAM_FIELDS = tuple(f.name for f in dataclasses.fields(PipelineSettings) if f.name != "registration")


def settings_from(values: Mapping[str, object]) -> PipelineSettings:
    """PipelineSettings from option values (any surface's; the others are checked and left out).

    Missing stream and algorithm options take their table defaults. Raises ValueError with the
    reason for an unknown option, a value of the wrong type, out of range or not among the
    choices, and anything the core refuses.
    """
    given = checked(values)
    stream = {**defaults(STREAM), **given}
    algorithm = {
        o.name: stream[o.name] for o in options_for(EVERYWHERE, [Group.ALGORITHM]) if o.name in stream
    }
    stream_fields: dict[str, Any] = {name: stream[name] for name in _STREAM_FIELDS}  # types checked above
    return PipelineSettings(registration=registration_config(algorithm), **stream_fields)


# --- config/frisicp.yaml --------------------------------------------------------------------------

YAML_HEADER = """\
# Parameters of the frisicp register_node, all of them, with their defaults.
# GENERATED from frisicp_ros/stream/settings.py by `make config`: edit the table there, not this
# file (a test checks the two agree).
# Load with: ros2 run frisicp_ros register_node --ros-args --params-file config/frisicp.yaml
# "/**" applies to the node under any name or namespace. Also shown by
# `ros2 param describe /frisicp <name>`.
/**:
  ros__parameters:
"""


def render_yaml() -> str:
    """The text of config/frisicp.yaml: every node parameter with its description and default."""
    lines = [YAML_HEADER.rstrip("\n")]
    for group in Group:
        rows = options_for(Surface.NODE, [group])
        if not rows:
            continue
        title = "algorithm (frisicp_core.RegistrationConfig)" if group is Group.ALGORITHM else group.value
        lines.append(f"    # --- {title} ---")
        for row in rows:
            comment = textwrap.wrap(
                _yaml_comment(row),
                100,
                initial_indent="    # ",
                subsequent_indent="    #   ",
                break_on_hyphens=False,
            )
            lines.extend(comment)
            lines.append(f"    {row.name}: {_yaml_value(row.default)}")
    return "\n".join(lines) + "\n"


def _yaml_comment(row: Option) -> str:
    notes = []
    if row.choices is not None and not all(choice in row.description for choice in row.choices):
        notes.append("one of " + " | ".join(row.choices))
    if row.bounds is not None:
        notes.append(f"range [{_number(row.bounds[0])}, {_number(row.bounds[1])}]")
    if row.rule is not None:
        notes.append(row.rule.text)
    if row.read_only:
        notes.append("read-only")
    return row.description + (f" ({'; '.join(notes)})" if notes else "")


def _yaml_value(value: Value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        text = repr(value)
        mantissa, e, exponent = text.partition("e")
        # YAML 1.1 readers (PyYAML) take 1e-05 for a string: give the mantissa a point.
        return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text
    if isinstance(value, int):
        return str(value)
    plain = value.replace("_", "").replace("-", "").isalnum() and value[0].isalpha()
    return value if plain and value.lower() not in _YAML_WORDS else f'"{value}"'


_YAML_WORDS = {"true", "false", "yes", "no", "on", "off", "null", "y", "n"}  # would not read as strings


# --- the parameter tables of docs/node.md and README.md ------------------------------------------

TABLE_BEGIN = "<!-- parameters: generated from frisicp_ros/stream/settings.py by `make config` -->"
TABLE_END = "<!-- end of the generated parameters -->"


def render_markdown_table() -> str:
    """Every node parameter as a Markdown table: name, type, default, range or choices, meaning."""
    rows = [
        TABLE_BEGIN,
        "",
        "| parameter | type | default | range / choices | meaning |",
        "|---|---|---|---|---|",
    ]
    for group in Group:
        for row in options_for(Surface.NODE, [group]):
            limits = " \\| ".join(row.choices) if row.choices else ""
            if row.bounds is not None:
                limits = f"[{_number(row.bounds[0])}, {_number(row.bounds[1])}]"
            default = _yaml_value(row.default) if row.default != "" else '""'
            flags = f" ({group.value}{', read-only' if row.read_only else ''})"
            rows.append(
                f"| `{row.name}` | {row.kind.__name__} | `{default}` | {limits} | {row.description}{flags} |"
            )
    rows += ["", TABLE_END]
    return "\n".join(rows)


def with_table(text: str) -> str:
    """``text`` (a Markdown file) with its generated parameter table replaced by the current one."""
    begin, end = text.index(TABLE_BEGIN), text.index(TABLE_END) + len(TABLE_END)
    return text[:begin] + render_markdown_table() + text[end:]


if __name__ == "__main__":
    import sys

    if sys.argv[1:2] == ["--markdown"]:  # rewrite the tables of the given Markdown files
        for name in sys.argv[2:]:
            with open(name, encoding="utf-8") as file:
                current = file.read()
            with open(name, "w", encoding="utf-8") as file:
                file.write(with_table(current))
    else:
        print(render_yaml(), end="")
