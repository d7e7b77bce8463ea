"""The emulated CMOS Ising chip, the logical Ising solver and the mapping toolkit.

Knows Ising models and hardware, not robots: imports no other project package.

Energy convention everywhere (paper eq. 2):
``E(s) = sum_i h_i s_i + sum_{i<j} J_ij s_i s_j + offset``, ``J`` strictly upper triangular.
"""

from .ledger import CallLedger
from .models import IsingModel, ModelError, QuboModel, from_bqm
from .spec import SCHEDULES, ChipSpec
from .chip import ChipProgramError, EmulatedChip, check_program, stack_programs

__all__ = [
    "CallLedger",
    "ChipProgramError",
    "ChipSpec",
    "EmulatedChip",
    "IsingModel",
    "ModelError",
    "QuboModel",
    "SCHEDULES",
    "check_program",
    "from_bqm",
    "stack_programs",
]
from .logical import LOGICAL_METHODS, LogicalIsingSolver, LogicalResult

__all__ += ["LOGICAL_METHODS", "LogicalIsingSolver", "LogicalResult"]
from .quantize import QUANTIZE_RULES, QuantizeError, quantize, saturate
from .merge import MERGE_STYLES, MergedModel, MergeError, merge_spins, saturate_mapping
from .branching import Branch, BranchError, branch, freeze_order, reduce_model
from .blocks import pack_blocks, plan_packs, unpack_blocks

__all__ += [
    "QUANTIZE_RULES", "QuantizeError", "quantize", "saturate",
    "MERGE_STYLES", "MergedModel", "MergeError", "merge_spins", "saturate_mapping",
    "Branch", "BranchError", "branch", "freeze_order", "reduce_model",
    "pack_blocks", "plan_packs", "unpack_blocks",
]
from .portfolio import (
    BranchMapping,
    IdentityMapping,
    MappedProgram,
    Mapping,
    MappingOutcome,
    MergeMapping,
    PortfolioResult,
    PortfolioStats,
    QuantizeMapping,
    SaturateMapping,
    merge_portfolio,
    quantize_portfolio,
    run_portfolio,
    run_portfolio_batch,
)

__all__ += [
    "BranchMapping", "IdentityMapping", "MappedProgram", "Mapping", "MappingOutcome", "MergeMapping",
    "PortfolioResult", "PortfolioStats", "QuantizeMapping", "SaturateMapping", "merge_portfolio",
    "quantize_portfolio", "run_portfolio", "run_portfolio_batch",
]
