"""The paper's three Ising methods, one sub-package each (formulation, decode/score, search, config).

* :mod:`planners.ising.path` -- patch-sliding pathfinding (section 5.1, Algorithm 1);
* :mod:`planners.ising.tour` -- clustered tour construction (section 5.2, Algorithm 2);
* :mod:`planners.ising.sharing` -- recursive target sharing (section 5.3, Algorithm 3).

Each planner takes ``chip=`` (a pipeline passes one chip, and so one ledger, to all
three) and ``config=`` (a frozen, validated dataclass) or the same options as keywords.
"""

from planners.ising.path import IsingPath, PathConfig
from planners.ising.sharing import IsingSharing, SharingConfig
from planners.ising.tour import IsingTour, TourConfig

__all__ = ["IsingPath", "PathConfig", "IsingTour", "TourConfig", "IsingSharing", "SharingConfig"]
