"""Clustered Ising tour construction (paper section 5.2, Algorithm 2).

``config`` (options), ``qubo`` (eq. 7 max-cut and one-hot open-path model builders,
decoders, scorers), ``cluster`` (clustering and cluster ordering), ``search`` (the
construction: local TSPs, patch refinement, starts).
"""

from planners.ising.tour.cluster import TourFailure
from planners.ising.tour.config import (
    BACKENDS, CLUSTER_DISTANCES, DEFAULT_SOLVER_OPTIONS, EXIT_COSTS, REFINE_RULES, TourConfig,
)
from planners.ising.tour.search import IsingTour, PaperIsingTour

__all__ = ["IsingTour", "PaperIsingTour", "TourConfig", "TourFailure", "REFINE_RULES", "CLUSTER_DISTANCES", "EXIT_COSTS", "BACKENDS",
           "DEFAULT_SOLVER_OPTIONS"]
