"""One machine boundary: sessions, the protocol's members, adapters for minimal drivers and solvers."""

from __future__ import annotations

import re
from pathlib import Path

import numba
import numpy as np
import pytest

from ising_backend import (CallLedger, ChipSpec, DriverMachine, EmulatedChip, IsingMachine, LogicalDriver,
                           LogicalIsingSolver, MachineBase, anneal_submit, as_logical_solver, as_machine,
                           solve_submit, via_callback)
from ising_backend.machines.link import _SESSIONS

ROOT = Path(__file__).resolve().parents[1]


@numba.njit(cache=True)
def _submit_twice(h, J, reads, machine):
    """A compiled loop of two submissions on a session record: (calls, seconds) per submission."""
    calls = np.zeros(2, dtype=np.int64)
    emu = np.zeros(2)
    for k in range(2):
        spins = np.empty((h.shape[0], reads, h.shape[1]), dtype=np.int8)
        energies = np.empty((h.shape[0], reads))
        emu[k] = anneal_submit(h, J, reads, np.uint64(11 + k), machine, spins, energies)
        calls[k] = h.shape[0] * reads
    return calls, emu, spins


def _programs(seed=0, B=3, n=6):
    rng = np.random.default_rng(seed)
    h = rng.integers(-7, 8, size=(B, n)).astype(np.int64)
    J = np.triu(rng.integers(-7, 8, size=(B, n, n)), 1).astype(np.int64)
    return h, J


class _Minimal:
    """A driver with only spec, ledger and anneal_batch (the emulator underneath)."""

    def __init__(self):
        self.inner = EmulatedChip(seed=0)
        self.spec = self.inner.spec
        self.ledger = self.inner.ledger

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        return self.inner.anneal_batch(h, J, num_reads=num_reads, seed=seed)


def test_direct_session_charges_what_anneal_batch_charges():
    h, J = _programs()
    chip, ref = EmulatedChip(seed=0), EmulatedChip(seed=0)
    ledger = CallLedger()
    with chip.session(ledger) as link:
        assert link.direct and not via_callback(link.args)
        calls, emu, spins = _submit_twice(h, J, 2, link.args)
        link.settle(calls, emu)
    expect = [ref.anneal_batch(h, J, num_reads=2, seed=11 + k)[0] for k in range(2)]
    assert np.array_equal(spins, expect[1])
    # two submissions of 3 programs x 2 reads, on the chip's ledger and the session's alike
    assert chip.ledger.physical_calls == ledger.physical_calls == 12 == ref.ledger.physical_calls
    assert chip.ledger.batches == ledger.batches == ref.ledger.batches


@pytest.mark.parametrize("make", [lambda: EmulatedChip(ChipSpec(dead_cores=1), seed=0),
                                  lambda: DriverMachine(_Minimal())])
def test_callback_session_charges_its_ledger_as_it_runs_and_unregisters(make):
    h, J = _programs(1)
    machine = make()
    ledger = CallLedger()
    before = machine.ledger.physical_calls
    with machine.session(ledger) as link:
        assert not link.direct and via_callback(link.args) and link.handle in _SESSIONS
        calls, emu, _spins = _submit_twice(h, J, 2, link.args)
        link.settle(calls, emu)  # a callback machine charged itself: nothing more
    assert link.handle not in _SESSIONS
    assert ledger.physical_calls == machine.ledger.physical_calls - before == int(calls.sum()) == 12


def test_logical_session_runs_the_tabu_kernel_or_the_callback():
    rng = np.random.default_rng(2)
    h = rng.normal(size=(2, 5))
    J = np.triu(rng.normal(size=(2, 5, 5)), 1)
    for solver, direct in ((LogicalIsingSolver(seed=0), True), (LogicalIsingSolver(method="dwave-tabu"), False)):
        ledger = CallLedger()
        with solver.session(ledger) as link:
            assert link.direct is direct
            spins = np.empty((2, 3, 5), dtype=np.int8)
            t = solve_submit(h, J, 3, np.uint64(5), link.args_for(5), spins, np.empty((2, 3)))
            link.settle(np.array([6]), np.array([t]))
        assert ledger.logical_calls == 6 and np.isin(spins, (-1, 1)).all()
        with pytest.raises(TypeError, match="args_for"):
            EmulatedChip().session(ledger).args_for(5)


def test_every_machine_has_every_member_the_package_uses():
    members = ("spec", "ledger", "last_call", "health", "usable_spins", "anneal_batch", "anneal_models", "session")
    for m in (EmulatedChip(seed=0), LogicalIsingSolver(), DriverMachine(_Minimal()),
              EmulatedChip(ChipSpec(stuck_spins=2), seed=0)):
        assert isinstance(m, IsingMachine) and isinstance(m, (MachineBase, LogicalIsingSolver))
        assert all(hasattr(m, a) for a in members)
    assert EmulatedChip(ChipSpec(stuck_spins=2), seed=0).usable_spins < 45


def test_as_machine_gives_the_default_chip_and_wraps_minimal_drivers():
    chip = as_machine()
    assert isinstance(chip, EmulatedChip) and chip.spec == ChipSpec()
    driver = _Minimal()
    m = as_machine(driver)
    assert isinstance(m, DriverMachine) and m.ledger is driver.ledger and as_machine(m) is m
    h, J = _programs(3)
    m.anneal_batch(h, J, num_reads=2, seed=1)
    assert m.last_call.physical_calls == 6 == driver.ledger.physical_calls
    with pytest.raises(TypeError, match="missing spec, ledger, anneal_batch"):
        as_machine(object())


def test_minimal_logical_solver_is_adapted():
    class Minimal:
        def __init__(self):
            self.inner = LogicalIsingSolver(seed=0)
            self.ledger = self.inner.ledger

        def solve_many(self, models, num_reads=1, seed=None):
            return self.inner.solve_many(models, num_reads=num_reads, seed=seed)

    s = as_logical_solver(Minimal())
    assert isinstance(s, LogicalDriver) and not s.session(CallLedger()).direct
    spins = s.solve_stack(np.zeros((2, 4)), np.zeros((2, 4, 4)), num_reads=3, seed=1)
    assert spins.shape == (2, 3, 4) and s.last_call.logical_calls == 6
    with pytest.raises(TypeError, match="solve_many"):
        as_logical_solver(object())


def test_planners_never_name_an_emulator_setting_nor_probe_a_machine():
    settings = re.compile(r"\b(sweeps|beta_hot|beta_cold|flip_prob|mismatch|kernel_args|readout_flip_prob|"
                          r"coupling_mismatch|beta_range)\b")
    probe = re.compile(r"\b(getattr|hasattr)\((self\.)?(chip|machine|solver|_chip|_solver)\b")
    found = []
    for path in sorted((ROOT / "planners").rglob("*.py")):
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if settings.search(line) or probe.search(line):
                found.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not found, "\n".join(found)


def test_a_callback_record_outside_its_session_is_a_clear_error():
    h, J = _programs(4)
    link = DriverMachine(_Minimal()).session(CallLedger())
    with pytest.raises(RuntimeError, match="outside its `with machine.session"):
        _submit_twice(h, J, 1, link.args)
