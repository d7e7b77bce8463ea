"""Patch-sliding Ising pathfinding (paper section 5.1, Algorithm 1).

``config`` (options), ``qubo`` (patch geometry and eq. 6 model builders),
``decode`` (samples -> local paths), ``search`` (the receding-horizon loop).
"""

from planners.ising.path.config import DEFAULT_SCALE, DEFAULT_WEIGHTS, FORMS, TARGET_ORDERS, PathConfig
from planners.ising.path.decode import decode_paths
from planners.ising.path.qubo import PatchFrame, PatchQubo, build_patch_qubo, patch_frame
from planners.ising.path.search import IsingPath, PaperIsingPath

__all__ = [
    "IsingPath", "PaperIsingPath", "PathConfig", "FORMS", "TARGET_ORDERS", "DEFAULT_SCALE", "DEFAULT_WEIGHTS",
    "PatchFrame", "PatchQubo", "patch_frame", "build_patch_qubo", "decode_paths",
]
