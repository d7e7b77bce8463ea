"""Ising tour construction: move selection on the physical chip, and the clustered construction
of paper section 5.2 (Algorithm 2).

``config`` (options), ``search`` (``IsingTour``), ``selection`` (the chip backend, over
:mod:`planners.ising.moves`), ``cluster`` (clustering and cluster ordering), ``onehot`` (the one-hot and
max-cut programs), ``engine`` (the one-hot subproblem solve) and ``kernels`` (model builders, decoders),
compiled.  Design notes: docs/design/ising_tour.md.
"""

from planners.ising.tour.cluster import TourFailure
from planners.ising.tour.config import (
    BACKENDS, CLUSTER_DISTANCES, DEFAULT_SOLVER_OPTIONS, EXIT_COSTS, REFINE_RULES, TourConfig,
)
from planners.ising.tour.search import IsingTour, PaperIsingTour

__all__ = ["IsingTour", "PaperIsingTour", "TourConfig", "TourFailure", "REFINE_RULES", "CLUSTER_DISTANCES", "EXIT_COSTS", "BACKENDS",
           "DEFAULT_SOLVER_OPTIONS"]
