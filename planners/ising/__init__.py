"""The paper's three Ising methods, one sub-package each (formulation, decode/score, search, config).

* :mod:`planners.ising.path` -- patch-sliding pathfinding (section 5.1, Algorithm 1);
* :mod:`planners.ising.tour` -- clustered tour construction (section 5.2, Algorithm 2);
* :mod:`planners.ising.sharing` -- recursive target sharing (section 5.3, Algorithm 3).

Each takes ``chip=`` and ``config=`` (or the options as keywords).  Design notes: docs/design/host_path.md.
"""

from planners.ising.path import IsingPath, PathConfig
from planners.ising.sharing import IsingSharing, SharingConfig
from planners.ising.tour import IsingTour, TourConfig

__all__ = ["IsingPath", "PathConfig", "IsingTour", "TourConfig", "IsingSharing", "SharingConfig"]
