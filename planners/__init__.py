"""Pure planning: (world, distances) -> Plan.  Classical baselines and the Ising methods."""

from planners.compute import CPU_WATTS_PER_CORE, ComputeReport
from planners.plan import Plan, PlanError, RobotRoute, validate_plan

__all__ = ["ComputeReport", "CPU_WATTS_PER_CORE", "Plan", "PlanError", "RobotRoute", "validate_plan"]
