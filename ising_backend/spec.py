"""The chip specification: hardware limits, accounting numbers and emulation knobs.

Defaults are the paper's (sections 3 and 6.1): 45 all-to-all spins per core,
integer ``h_i`` and ``J_ij`` in ``[-7, +7]``, 4 chips x 2 cores = 8 parallel
cores, 50 us per solve, 9 mW (so 0.45 uJ per call).  Every field can be changed
for "what if" studies, e.g. ``ChipSpec(n_spins=100, h_range=(-15, 15),
j_range=(-15, 15))``.

Emulation knobs (the paper is silent; choices and reasons):

* ``sweeps=50``: a short fixed anneal.  50 Metropolis sweeps of all spins is
  about what a ring-oscillator chip's 50 us settle buys, and it keeps the
  emulator a *probabilistic* annealer (ground state on small programs most of
  the time, not always) as the paper's decode-validity numbers require.
* ``schedule="geometric"`` in inverse temperature from ``beta_range``; with
  ``beta_range=None`` the range is chosen per program (cold end: dwave-samplers'
  default rule, the smallest non-zero coefficient excites with probability 1 %;
  hot end: a flip against the largest root-mean-square local field is accepted
  with probability 1/2; see :mod:`ising_backend.anneal`).  ``"linear"`` is
  available too.
* ``coupling_mismatch=0.05``: static per-core analog mismatch.  Each of the
  ``n_cores`` cores gets a fixed symmetric matrix of multiplicative factors
  ``1 + 0.05 * N(0, 1)`` (drawn once from ``seed``) applied to the programmed
  couplings while annealing: a few percent device mismatch is typical of 65 nm
  coupling cells, and at 5 % a coefficient of 7 moves by about 0.35, less than
  half an integer step, so the program keeps its meaning.  Energies reported
  back are always those of the *programmed* (noise-free) coefficients.
* ``readout_flip_prob=0.0``: probability that each spin's read-out bit flips
  after the anneal.  The COBI chip samples oscillator phases digitally and the
  paper reports no readout errors, so the default is off; raise it to study
  decode robustness.
* ``seed=0``: the seed of the static hardware (the mismatch pattern), i.e. which
  physical chip you hold.  The sampling randomness is seeded per call.

``ChipSpec.noise_free()`` returns the same spec with both noise knobs at zero.
"""

from __future__ import annotations

import math

import numpy as np
from dataclasses import asdict, dataclass, replace

__all__ = ["ChipSpec", "SCHEDULES"]

SCHEDULES = ("geometric", "linear")


@dataclass(frozen=True)
class ChipSpec:
    """Hardware limits, accounting numbers and emulation knobs of the emulated chip."""

    n_spins: int = 45
    h_range: tuple[int, int] = (-7, 7)
    j_range: tuple[int, int] = (-7, 7)
    n_chips: int = 4
    cores_per_chip: int = 2
    solve_time_s: float = 50e-6
    power_w: float = 9e-3
    sweeps: int = 50
    schedule: str = "geometric"
    beta_range: tuple[float, float] | None = None
    coupling_mismatch: float = 0.05
    readout_flip_prob: float = 0.0
    seed: int = 0

    def __post_init__(self):
        def bad(msg):
            raise ValueError(f"ChipSpec: {msg}")

        if int(self.n_spins) != self.n_spins or self.n_spins < 1:
            bad(f"n_spins = {self.n_spins!r} must be a positive integer")
        for name in ("h_range", "j_range"):
            r = tuple(getattr(self, name))
            if len(r) != 2 or not (r[0] <= 0 <= r[1]) or r[0] == r[1]:
                bad(f"{name} = {r!r} must be (low <= 0 <= high) with low < high")
            if any(int(v) != v for v in r):
                bad(f"{name} = {r!r} must hold integers")
            object.__setattr__(self, name, (int(r[0]), int(r[1])))
        for name in ("n_chips", "cores_per_chip", "sweeps"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                bad(f"{name} = {v!r} must be a positive integer")
        if not (self.solve_time_s > 0 and math.isfinite(self.solve_time_s)):
            bad(f"solve_time_s = {self.solve_time_s!r} must be positive")
        if not (self.power_w >= 0 and math.isfinite(self.power_w)):
            bad(f"power_w = {self.power_w!r} must be >= 0")
        if self.schedule not in SCHEDULES:
            bad(f"schedule = {self.schedule!r} not in {SCHEDULES}")
        if self.beta_range is not None:
            b = tuple(float(v) for v in self.beta_range)
            if len(b) != 2 or not (0 < b[0] <= b[1]) or not all(math.isfinite(v) for v in b):
                bad(f"beta_range = {self.beta_range!r} must be (beta_hot, beta_cold) with 0 < hot <= cold")
            object.__setattr__(self, "beta_range", b)
        if not (0 <= self.coupling_mismatch < 1):
            bad(f"coupling_mismatch = {self.coupling_mismatch!r} must be in [0, 1)")
        if not (0 <= self.readout_flip_prob <= 0.5):
            bad(f"readout_flip_prob = {self.readout_flip_prob!r} must be in [0, 0.5]")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**63:
            bad(f"seed = {self.seed!r} must be an integer in [0, 2**63) (the hardware's mismatch pattern)")

    @property
    def n_cores(self) -> int:
        """Parallel solver cores (chips x cores per chip): programs per batch."""
        return self.n_chips * self.cores_per_chip

    @property
    def energy_per_call_j(self) -> float:
        """Accelerator energy of one call: power x solve time (0.45 uJ by default)."""
        return self.power_w * self.solve_time_s

    def noise_free(self) -> "ChipSpec":
        """This spec with coupling mismatch and readout flips switched off."""
        return replace(self, coupling_mismatch=0.0, readout_flip_prob=0.0)

    def replace(self, **changes) -> "ChipSpec":
        return replace(self, **changes)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["n_cores"] = self.n_cores
        d["energy_per_call_j"] = self.energy_per_call_j
        return d
