"""The compiled QUBO-to-Ising conversion (``ising_backend.mapping.numeric.ising_of_qubo``) checked by energies.

Its other test compares it bit for bit with the host's conversion (``ising_from_qubo``), which a shared mistake would
pass.  Here dimod's ``BinaryQuadraticModel`` is the independent reference: for every spin vector ``s`` of a random
QUBO's size, the Ising model's energy at ``s`` equals the QUBO's energy at ``x = (1 + s) / 2`` (offsets included).
Coefficients in eighths make every energy exact (the conversion halves and quarters them), so the check is equality.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ising_backend.mapping.numeric import ising_of_qubo

dimod = pytest.importorskip("dimod")


def _energies(linear: np.ndarray, upper: np.ndarray, offset: float, vartype: str, samples: np.ndarray) -> np.ndarray:
    n = len(linear)
    bqm = dimod.BinaryQuadraticModel({i: float(linear[i]) for i in range(n)},
                                     {(i, j): float(upper[i, j]) for i in range(n) for j in range(i + 1, n)
                                      if upper[i, j] != 0},
                                     float(offset), vartype)
    return np.asarray(bqm.energies((samples, list(range(n)))))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(1, 9), offset=st.integers(-100, 100))
def test_the_ising_energy_of_every_spin_vector_is_the_qubos(seed, n, offset):
    rng = np.random.default_rng(seed)
    q = rng.integers(-320, 321, size=n) / 8.0  # eighths: every energy on both sides is exact in float64
    Q = np.triu(rng.integers(-320, 321, size=(n, n)), k=1) / 8.0
    h, J, ising_offset = ising_of_qubo(q, Q, float(offset))
    assert np.array_equal(J, np.triu(J, k=1))  # couplings strictly upper, as the QUBO's
    spins = np.array(list(itertools.product((-1, 1), repeat=n)), dtype=np.int8)
    binary = ((spins + 1) // 2).astype(np.int8)
    ising = _energies(h, J, ising_offset, "SPIN", spins)
    qubo = _energies(q, Q, offset, "BINARY", binary)
    assert len(ising) == 2 ** n
    assert np.array_equal(ising, qubo)
