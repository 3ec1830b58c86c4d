"""frisicp_core: isotropic-scale point-set registration (FRISICP, Li et al. 2011) in numpy/scipy.

No ROS imports here; the ROS layer lives in ``frisicp_ros``.
"""

from .ambiguity import Competitor
from .config import ConvergenceCriteria, InitialGuess, Initialization, Method, RegistrationConfig, Tolerance
from .estimate import estimate_similarity
from .fit import Fit
from .kdtree import NearestNeighbors, nearest
from .points import as_point_set
from .prepared import PreparedModel
from .registration import better_of, register, worse_than_track
from .result import IterationRecord, LevelReport, RegistrationResult
from .sampling import downsample
from .shapes import bumpy_surface, closed_contour
from .similarity import Similarity, axis_angle_rotation, rotation_angle
from .uncertainty import Uncertainty
from .verdict import Verdict, judge

__all__ = [
    "Competitor",
    "ConvergenceCriteria",
    "Fit",
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
    "judge",
    "nearest",
    "register",
    "rotation_angle",
    "worse_than_track",
]
__version__ = "0.1.0"
