"""The experiments of paper section 6 (path, tour, sharing, end to end, Table 5), their
figures and ``summary.md``; ``reproduce`` runs them all.  One row per (instance, method);
instance ``i`` is world seed ``seed + i`` for every method.  Time and energy columns carry
the paper's convention (``time_s``, ``energy_j``) and the system's (host CPU included)
side by side.  Choices and column definitions: docs/design/experiments.md.
"""

from __future__ import annotations

from agents.experiments.figures import plot_experiment
from agents.experiments.layers import make_layer
from agents.experiments.paper import (ENDTOEND_METHODS, METHOD_LABELS, PAPER, PAPER_SIZES, PATH_METHODS,
                                      QUICK_SIZES, SHARING_METHODS, TOUR_METHODS)
from agents.experiments.records import ExperimentResult, write_rows
from agents.experiments.run import (endtoend_experiment, path_experiment, reproduce, sharing_experiment,
                                    tour_experiment)
from agents.experiments.summary import mapping_table, summarize, write_summary

__all__ = [
    "PAPER",
    "PAPER_SIZES",
    "QUICK_SIZES",
    "METHOD_LABELS",
    "PATH_METHODS",
    "TOUR_METHODS",
    "SHARING_METHODS",
    "ENDTOEND_METHODS",
    "ExperimentResult",
    "make_layer",
    "path_experiment",
    "tour_experiment",
    "sharing_experiment",
    "endtoend_experiment",
    "mapping_table",
    "summarize",
    "plot_experiment",
    "write_summary",
    "write_rows",
    "reproduce",
]
