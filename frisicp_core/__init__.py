"""frisicp_core: isotropic-scale point-set registration (FRISICP, Li et al. 2011) in numpy/scipy.

No ROS imports here; the ROS layer lives in ``frisicp_ros``.
"""

from .config import ConvergenceCriteria, Initialization, Method, RegistrationConfig
from .estimate import estimate_similarity
from .kdtree import NearestNeighbors, nearest
from .points import as_point_set
from .registration import register
from .result import IterationRecord, LevelReport, RegistrationResult
from .sampling import downsample
from .shapes import bumpy_surface, closed_contour
from .similarity import Similarity, axis_angle_rotation, rotation_angle
from .verdict import Verdict, judge

__all__ = [
    "ConvergenceCriteria",
    "Initialization",
    "IterationRecord",
    "LevelReport",
    "Method",
    "NearestNeighbors",
    "RegistrationConfig",
    "RegistrationResult",
    "Similarity",
    "Verdict",
    "as_point_set",
    "axis_angle_rotation",
    "bumpy_surface",
    "closed_contour",
    "downsample",
    "estimate_similarity",
    "judge",
    "nearest",
    "register",
    "rotation_angle",
]
__version__ = "0.1.0"
