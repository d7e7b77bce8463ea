"""Fleet-scale Ising routing: chip-selected moves between robots in an iterated local search."""

from planners.ising.fleet.search import FleetConfig, IsingFleetSharing

__all__ = ["FleetConfig", "IsingFleetSharing"]
