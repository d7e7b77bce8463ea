"""Ising tour construction: move selection on the physical chip, and the clustered construction
of paper section 5.2 (Algorithm 2).

``config`` (options), ``selection`` (the chip backend: starts over the move engine of
:mod:`planners.ising.moves`), ``engine`` (the
one-hot subproblem solve, compiled), ``qubo``
(eq. 7 max-cut and one-hot open-path model builders, decoders, scorers), ``cluster``
(clustering and cluster ordering), ``search`` (``IsingTour``: local TSPs, patch refinement,
starts; dispatch to the chip backend).
"""

from planners.ising.tour.cluster import TourFailure
from planners.ising.tour.config import (
    BACKENDS, CLUSTER_DISTANCES, DEFAULT_SOLVER_OPTIONS, EXIT_COSTS, REFINE_RULES, TourConfig,
)
from planners.ising.tour.search import IsingTour, PaperIsingTour

__all__ = ["IsingTour", "PaperIsingTour", "TourConfig", "TourFailure", "REFINE_RULES", "CLUSTER_DISTANCES", "EXIT_COSTS", "BACKENDS",
           "DEFAULT_SOLVER_OPTIONS"]
