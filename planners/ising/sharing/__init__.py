"""Recursive Ising target sharing (paper section 5.3, Algorithm 3).

``search`` (``IsingSharing``), ``stages`` over ``stage_steps`` (a stage's splits and chip submissions,
compiled), ``submission`` (program record, refusals), ``split_problem`` (the anchored eq. 8 split QUBO,
branches, read scoring), ``clusters`` (coarse splits), ``placement`` (bundle placement and pricing),
``refine`` (pair re-splits), ``node_sets``, ``bundles``, ``components``, ``config``.
Design notes: docs/design/ising_sharing.md.
"""

from planners.ising.sharing.bundles import BundlePricer, SharingFailure
from planners.ising.sharing.config import BUNDLE_ORDERS, SharingConfig
from planners.ising.sharing.split_problem import add_balance, split_model
from planners.ising.sharing.search import IsingSharing, PaperIsingSharing

__all__ = ["IsingSharing", "PaperIsingSharing", "SharingConfig", "BUNDLE_ORDERS", "split_model", "add_balance",
           "BundlePricer", "SharingFailure"]
