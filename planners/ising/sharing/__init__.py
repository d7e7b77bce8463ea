"""Recursive Ising target sharing (paper section 5.3, Algorithm 3).

``search`` (``IsingSharing``: the search), ``stages`` (the split stages) over ``stage_steps`` (a
stage's splits and chip submissions, compiled), ``submission`` (the chip side: program record,
refusals), ``clusters`` (coarse splits of groups beyond the chip), ``placement`` (bundle placement
and pricing), ``refine`` (pair re-splits), ``kernels`` (the anchored eq. 8 split QUBO, spin-budget
branches, read scoring), ``node_sets`` (node sets as ids), ``bundles`` (pricing by any tour
solver), ``config`` (options).
"""

from planners.ising.sharing.bundles import BundlePricer, SharingFailure
from planners.ising.sharing.config import BUNDLE_ORDERS, SharingConfig
from planners.ising.sharing.split_problem import add_balance, split_model
from planners.ising.sharing.search import IsingSharing, PaperIsingSharing

__all__ = ["IsingSharing", "PaperIsingSharing", "SharingConfig", "BUNDLE_ORDERS", "split_model", "add_balance",
           "BundlePricer", "SharingFailure"]
