"""The emulated CMOS Ising chip, the logical Ising solver and the mapping toolkit (Ising models, not robots).
Design notes: docs/design/emulated_chip.md#the-package-and-its-energy-convention. Example::

    >>> from ising_backend import EmulatedChip, IsingModel, merge_portfolio, run_portfolio
    >>> model = IsingModel([12.0, -3.0, 1.0], [[0, -9.0, 2.0], [0, 0, 4.0], [0, 0, 0]])
    >>> chip = EmulatedChip(seed=0)
    >>> result = run_portfolio(model, merge_portfolio(), chip, num_reads=4, seed=1)
    >>> float(result.best_score), chip.ledger.physical_calls
    (-23.0, 16)
"""

from ising_backend._rng import splitmix
from ising_backend.ledger import CallLedger
from ising_backend.models import IsingModel, ModelError, QuboModel, from_bqm, ising_from_qubo
from ising_backend.spec import DEAD_CORE_MODES, SCHEDULES, ChipSpec
from ising_backend.faults.model import FaultMap
from ising_backend.faults.health import ChipUnavailableError, HealthMonitor, SolverOutputError
from ising_backend.machines.chip import ChipProgramError, EmulatedChip, check_program, kernel_capable, programs_fit, stack_programs
from ising_backend.machines.logical import LOGICAL_METHODS, LogicalIsingSolver, LogicalResult
from ising_backend.meter import MeteredSolver
from ising_backend.mapping.quantize import QUANTIZE_RULES, QuantizeError, quantize, quantize_stack, saturate
from ising_backend.mapping._quantize_kernel import RULE_IDS as QUANTIZE_RULE_IDS, integer_program, quantize_rules
from ising_backend.mapping.merge import MERGE_STYLES, MergedModel, MergeError, merge_error_message, merge_spins, saturate_mapping
from ising_backend.mapping._merge_kernel import STYLE_IDS as MERGE_STYLE_IDS, merge_styles, merge_styles_flat
from ising_backend.mapping.branching import Branch, BranchError, branch, freeze_order
from ising_backend.mapping.blocks import fill_packs, pack_blocks, pack_layout, plan_packs, unpack_blocks
from ising_backend.mapping.stack import STACK_NONFINITE, STACK_OK, STACK_UNFIT, pack_qubo_stack, submit_packs
from ising_backend.mapping.portfolio import (
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
from ising_backend.machines.composite import COMPOSITE_RULES, QuantizeComposite
from ising_backend.mapping.mapping_stats import MAPPING_FIELDS, add_counts, mapping_record, record_of_reads
from ising_backend.machines.link import AnnealArgs, MachineSession, SolverArgs, anneal_submit, solve_submit, via_callback
from ising_backend.machines.machine import (SAMPLERS, DriverMachine, LogicalDriver, as_logical_solver, IsingMachine, MachineBase, MachineSpec, SamplerChip, as_machine, build_machine,
                      sampler_names)

__all__ = [
    # models, spec, ledger
    "IsingModel", "QuboModel", "ModelError", "from_bqm", "ising_from_qubo", "ChipSpec", "SCHEDULES", "CallLedger",
    # Ising machines
    "IsingMachine", "MachineBase", "SamplerChip", "DriverMachine", "LogicalDriver", "as_logical_solver", "MachineSpec", "SAMPLERS", "as_machine", "build_machine",
    "sampler_names", "MachineSession", "AnnealArgs", "SolverArgs", "anneal_submit", "solve_submit", "via_callback",
    # chip
    "EmulatedChip", "ChipProgramError", "check_program", "stack_programs", "kernel_capable", "programs_fit",
    # faults
    "DEAD_CORE_MODES", "FaultMap", "HealthMonitor", "ChipUnavailableError",
    # logical solver
    "LogicalIsingSolver", "LogicalResult", "LOGICAL_METHODS",
    # metering
    "MeteredSolver", "SolverOutputError",
    # mapping toolkit
    "QUANTIZE_RULES", "QuantizeError", "quantize", "quantize_stack", "saturate", "quantize_rules", "integer_program",
    "QUANTIZE_RULE_IDS",
    "MERGE_STYLES", "MergedModel", "MergeError", "merge_spins", "saturate_mapping", "merge_styles", "merge_styles_flat",
    "merge_error_message", "MERGE_STYLE_IDS",
    "Branch", "BranchError", "branch", "freeze_order",
    "fill_packs", "pack_blocks", "pack_layout", "plan_packs", "unpack_blocks", "pack_qubo_stack", "submit_packs",
    "STACK_OK", "STACK_NONFINITE", "STACK_UNFIT",
    # portfolio
    "BranchMapping", "IdentityMapping", "MappedProgram", "Mapping", "MappingOutcome", "MergeMapping",
    "PortfolioResult", "PortfolioStats", "QuantizeMapping", "SaturateMapping", "merge_portfolio",
    "quantize_portfolio", "run_portfolio", "run_portfolio_batch", "MAPPING_FIELDS", "mapping_record", "record_of_reads", "add_counts",
    # dimod composite
    "QuantizeComposite", "COMPOSITE_RULES",
    # the compiled splitmix64 step every seeded kernel of the package hashes with
    "splitmix",
]
