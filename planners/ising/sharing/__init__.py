"""Recursive Ising target sharing (paper section 5.3, Algorithm 3).

``config`` (options), ``kernels`` (the anchored eq. 8 split QUBO, spin-budget branches, read
scoring), ``engine`` (a stage's chip submission in one compiled call), ``compiled_stages`` /
``compiled_coarse`` / ``compiled_assign`` (the whole search in one compiled call: split stages,
coarse splits of groups beyond the chip, bundle placement, pair re-splits), ``node_sets``
(its node sets), ``bundles`` (bundle pricing by a tour solver), ``search`` (``IsingSharing``).
"""

from planners.ising.sharing.bundles import BundlePricer, SharingFailure
from planners.ising.sharing.config import BUNDLE_ORDERS, SharingConfig
from planners.ising.sharing.kernels import add_balance, split_model
from planners.ising.sharing.search import IsingSharing, PaperIsingSharing

__all__ = ["IsingSharing", "PaperIsingSharing", "SharingConfig", "BUNDLE_ORDERS", "split_model", "add_balance",
           "BundlePricer", "SharingFailure"]
