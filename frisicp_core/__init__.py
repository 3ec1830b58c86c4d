"""frisicp_core: isotropic-scale point-set registration (FRISICP, Li et al. 2011) in numpy/scipy.

No ROS imports here; the ROS layer lives in ``frisicp_ros``.
"""

from .ambiguity import Competitor
from .config import ConvergenceCriteria, InitialGuess, Initialization, Method, RegistrationConfig, Tolerance
from .depth_steps import DepthSteps, find_depth_steps
from .estimate import estimate_similarity
from .fit import Fit
from .io import CloudFileError, read_points, read_scan_pose
from .kdtree import BACKENDS, NearestNeighbors, nearest
from .points import as_point_set
from .prepared import PreparedModel
from .registration import better_of, register, worse_than_track
from .result import IterationRecord, LevelReport, RegistrationResult
from .sampling import downsample
from .shapes import bumpy_surface, closed_contour
from .similarity import FloatArray, Similarity, axis_angle_rotation, rotation_angle
from .uncertainty import Uncertainty
from .verdict import Verdict, judge
from .voxel import voxel_centroids, voxel_filter

__all__ = [
    "BACKENDS",
    "CloudFileError",
    "Competitor",
    "ConvergenceCriteria",
    "DepthSteps",
    "Fit",
    "FloatArray",
    "InitialGuess",
    "Initialization",
    "IterationRecord",
    "LevelReport",
    "Method",
    "NearestNeighbors",
    "PreparedModel",
    "RegistrationConfig",
    "RegistrationResult",
    "Similarity",
    "Tolerance",
    "Uncertainty",
    "Verdict",
    "as_point_set",
    "axis_angle_rotation",
    "better_of",
    "bumpy_surface",
    "closed_contour",
    "downsample",
    "estimate_similarity",
    "find_depth_steps",
    "judge",
    "nearest",
    "read_points",
    "read_scan_pose",
    "register",
    "rotation_angle",
    "voxel_centroids",
    "voxel_filter",
    "worse_than_track",
]
__version__ = "0.1.0"
