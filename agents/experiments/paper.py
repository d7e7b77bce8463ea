"""The paper's numbers (section 6.2, Table 5), its instance counts and the methods compared.

Values are quoted from the paper so ``summary.md`` can set every measured statistic beside
the paper's; ``None`` marks a statistic the paper does not give.
"""

from __future__ import annotations

#: Instances per experiment at the paper's sizes (section 6.2) and for ``--quick``.
PAPER_SIZES = {"path": 1000, "tour": 100, "sharing": 100, "endtoend": 100}
QUICK_SIZES = {"path": 40, "tour": 8, "sharing": 8, "endtoend": 4}

#: Display names (figures and tables).
METHOD_LABELS = {
    "bfs": "BFS",
    "astar": "A*",
    "gbfs": "GBFS",
    "nn": "NN",
    "2opt": "2-opt",
    "3opt": "3-opt",
    "brute": "Exact",
    "round_robin": "Round robin",
    "psa": "PSA",
    "ssa": "SSA",
    "exact": "Exact",
    "ising": "Ising",
    "pyvrp": "PyVRP",
    "fast": "Fast classical",
    "strong": "Strong classical",
}

#: The paper's numbers (section 6.2 and Table 5), keyed like :func:`summarize`'s statistics.
PAPER = {
    "path": {
        "ising success": "996/1000",
        "classical success": "1000/1000",
        "ising median path length": 6.0,
        "bfs median path length": 6.0,
        "ising median chip calls": 32,
        "ising median chip time (ms)": 1.6,
        "ising median energy (uJ)": 14.0,
        "astar median time (us)": 35.0,
        "astar median energy (uJ)": 523.0,
        "energy ratio astar / ising": 37.0,
    },
    "tour": {
        "ising median gap (%)": 0.0,
        "ising mean gap (%)": 1.63,
        "nn mean gap (%)": 11.61,
        "2opt mean gap (%)": 4.62,
        "3opt mean gap (%)": 1.31,
        "ising median logical calls": 98,
        "ising median chip time (ms)": 4.9,
        "ising median energy (uJ)": 44.0,
        "energy ratio 3opt / ising": 770.0,
    },
    "sharing": {
        "ssa median total": 28.0,
        "ising median total": 29.0,
        "exact median total": None,
        "ising median gap to best (%)": 2.78,
        "ssa median gap to best (%)": 0.0,
        "ssa median makespan": 16.0,
        "ising median makespan": 16.0,
        "ssa median imbalance": 14.0,
        "ising median imbalance": 12.0,
        "ising median chip calls": 20,
        "ising median chip batches": 5,
        "ising median chip time (ms)": 1.0,
        "ising median energy (uJ)": 9.0,
        "ssa median energy (mJ)": 73.0,
        "energy ratio ssa / ising": 8000.0,
    },
    "endtoend": {
        "ising median total": 32.0,
        "strong median total": 28.0,
        "fast median total": 45.0,
        "ising median gap to strong (%)": 9.1,
        "ising median energy (mJ)": 3.07,
        "strong median energy (mJ)": 399.0,
        "fast median energy (mJ)": 14.8,
        "ising median latency (ms)": 341.0,
        "strong median latency (ms)": 27.0,
        "fast median latency (ms)": 0.99,
        "ising median path chip calls": 6720,
        "ising median sharing chip calls": 20,
        "ising median tour logical calls": 88,
        "energy ratio strong / ising": 130.0,
        "energy ratio fast / ising": 4.8,
    },
    "mapping": {
        ("path", "overload"): (44.8, 24.9),
        ("path", "max_coeff"): (45.1, 25.1),
        ("path", "high_degree"): (45.1, 25.0),
        ("path", "balanced"): (45.1, 25.0),
        ("sharing", "linear"): (25.0, 25.2),
        ("sharing", "clip95"): (25.0, 25.4),
        ("sharing", "rank"): (25.0, 25.3),
        ("sharing", "sqrt"): (25.0, 24.0),
    },
}

PATH_METHODS = ("bfs", "astar", "gbfs", "ising")
TOUR_METHODS = ("nn", "2opt", "3opt", "brute", "ising")
SHARING_METHODS = ("round_robin", "psa", "ssa", "exact", "ising")
ENDTOEND_METHODS = ("fast", "strong", "ising")
#: The strongest classical peer beside the paper's pipelines (when the ``peers`` extra is installed):
#: PyVRP stopped after a fixed number of iterations, so its plans are deterministic.
PEER_METHODS = ("pyvrp",)
PYVRP_OPTIONS = {"seconds": None, "iterations": 1000}


def endtoend_methods() -> tuple[str, ...]:
    """The end-to-end experiment's methods: the paper's three, and PyVRP where it is installed."""
    try:
        import pyvrp  # noqa: F401
    except ImportError:
        return ENDTOEND_METHODS
    return ENDTOEND_METHODS + PEER_METHODS
