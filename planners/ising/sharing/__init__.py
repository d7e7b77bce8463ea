"""Recursive Ising target sharing (paper section 5.3, Algorithm 3).

``config`` (options), ``qubo`` (anchored eq. 8 split builders, decode, cut score),
``submit`` (a stage's chip submission), ``coarse`` (groups beyond the chip split on target
clusters), ``boundary`` (pair re-splits after the recursion), ``bundles`` (bundle placement and
pricing on the host), ``search`` (the staged recursion).
"""

from planners.ising.sharing.bundles import BundlePricer, SharingFailure, assign_bundles
from planners.ising.sharing.config import BUNDLE_ORDERS, SharingConfig
from planners.ising.sharing.qubo import SplitProblem, build_split_qubo, choose_anchors, cut_value, decode_split
from planners.ising.sharing.search import IsingSharing, PaperIsingSharing

__all__ = ["IsingSharing", "PaperIsingSharing", "SharingConfig", "BUNDLE_ORDERS", "SplitProblem", "build_split_qubo", "choose_anchors",
           "cut_value", "decode_split", "BundlePricer", "SharingFailure", "assign_bundles"]
