"""The chip's fault model (dead cores, stuck spins, write errors) and its graceful degradation."""

import math

import dimod
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ising_backend import (
    CallLedger, ChipSpec, ChipUnavailableError, EmulatedChip, FaultMap, IsingModel, LogicalIsingSolver,
    MeteredSolver,
)
from ising_backend.machines.anneal import NO_CLAMP, NO_CORES, anneal_kernel
from ising_backend.faults.health import PROBE_READS

CLEAN = ChipSpec().noise_free()


def _random_program(n, seed=0, B=1):
    rng = np.random.default_rng(seed)
    h = rng.integers(-7, 8, (B, n))
    J = np.triu(rng.integers(-7, 8, (B, n, n)), 1)
    return h, J


def _forcing(n, value=1):
    """A program whose ground state is every spin at ``value`` (strong fields, no couplings)."""
    return -7 * value * np.ones((1, n), dtype=np.int64), np.zeros((1, n, n), dtype=np.int64)


def _same_ledger(a: CallLedger, b: CallLedger) -> bool:
    da, db = a.to_dict(), b.to_dict()
    da.pop("emulation_s"), db.pop("emulation_s")
    return da == db


# ------------------------------------------------------------------ spec
@pytest.mark.parametrize("field, value, words", [
    ("dead_cores", -1, "[0, n_cores = 8]"),
    ("dead_cores", 9, "[0, n_cores = 8]"),
    ("dead_cores", 1.5, "dead_cores = 1.5"),
    ("dead_cores", True, "dead_cores = True"),
    ("stuck_spins", 46, "[0, n_spins = 45]"),
    ("stuck_spins", -2, "stuck_spins = -2"),
    ("program_error_prob", 1.5, "[0, 1]"),
    ("program_error_prob", -0.1, "[0, 1]"),
    ("program_error_prob", math.nan, "[0, 1]"),
    ("max_retries", -1, "max_retries = -1"),
    ("dead_core_mode", "sleep", "('garbage', 'timeout')"),
])
def test_bad_fault_values_are_refused_naming_value_and_limit(field, value, words):
    with pytest.raises(ValueError, match="ChipSpec") as err:
        ChipSpec(**{field: value})
    assert words in str(err.value)


def test_fault_fields_from_options_and_defaults():
    spec = ChipSpec.from_options([("dead_cores", "1"), ("stuck_spins", 2), ("program_error_prob", "0.05"),
                                  ("dead_core_mode", "timeout"), ("max_retries", "5")])
    assert (spec.dead_cores, spec.stuck_spins, spec.program_error_prob, spec.dead_core_mode, spec.max_retries) == \
        (1, 2, 0.05, "timeout", 5)
    assert spec.faulty and not spec.fault_free().faulty and spec.fault_free().readout_flip_prob == 0
    assert not ChipSpec().faulty and not ChipSpec(readout_flip_prob=0.01).faulty
    with pytest.raises(ValueError, match="dead_cores = 12"):
        ChipSpec.from_options([("dead_cores", "12")])
    assert ChipSpec(cores_per_chip=1, n_chips=2, dead_cores=2).dead_cores == 2  # every core may be dead


def test_fault_free_chip_has_no_health_and_same_samples():
    chip = EmulatedChip(ChipSpec(), seed=0)
    assert chip.health is None and chip.usable_spins == 45 and chip.ledger.physical_calls == 0
    h, J = _random_program(30, B=3)
    spins, energies = chip.anneal_batch(h, J, num_reads=5, seed=7)
    assert chip.last_call.retries == 0 and chip.last_call.probe_calls == 0
    # the kernel with each read's core given as k % n_cores is the plain kernel
    spec = chip.spec
    out = np.empty_like(spins), np.empty_like(energies)
    anneal_kernel(h.astype(np.int64), J.astype(np.int64), 5, np.uint64(7), spec.sweeps, True, -1.0, -1.0,
                        chip._mismatch, 0.0, (np.arange(15) % 8, np.zeros((0, 0), dtype=np.int8)), out)
    assert np.array_equal(out[0], spins) and np.array_equal(out[1], energies)
    plain = np.empty_like(spins), np.empty_like(energies)
    anneal_kernel(h.astype(np.int64), J.astype(np.int64), 5, np.uint64(7), spec.sweeps, True, -1.0, -1.0,
                  chip._mismatch, 0.0, (NO_CORES, NO_CLAMP), plain)
    assert np.array_equal(plain[0], spins)


# ------------------------------------------------------------------ fault map
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**63 - 1), dead=st.integers(0, 8), stuck=st.integers(0, 45))
def test_fault_map_is_a_function_of_the_spec(seed, dead, stuck):
    spec = ChipSpec(seed=seed, dead_cores=dead, stuck_spins=stuck)
    a, b = FaultMap.from_spec(spec), FaultMap.from_spec(spec)
    assert np.array_equal(a.dead, b.dead) and np.array_equal(a.clamp, b.clamp)
    assert a.dead.sum() == dead
    assert ((a.clamp != 0).sum(axis=1) == stuck).all() and set(np.unique(a.clamp)) <= {-1, 0, 1}


def test_fault_map_depends_on_the_seed_and_leaves_mismatch_alone():
    maps = [FaultMap.from_spec(ChipSpec(seed=s, dead_cores=2, stuck_spins=3)) for s in range(6)]
    assert len({m.clamp.tobytes() for m in maps}) == 6
    assert np.array_equal(EmulatedChip(ChipSpec(stuck_spins=3))._mismatch, EmulatedChip(ChipSpec())._mismatch)


# ------------------------------------------------------------------ raw faults (no probe)
def test_stuck_spins_visible_in_raw_samples_of_their_core():
    spec = CLEAN.replace(stuck_spins=3, seed=4)
    chip = EmulatedChip(spec, probe=False)
    h, J = _random_program(45, seed=1)
    spins, _ = chip.anneal_batch(h, J, num_reads=24, seed=3)
    cores = chip.health.last_cores[0]
    assert sorted(np.bincount(cores, minlength=8)) == [3] * 8  # round-robin over the cores
    clamp = chip.faults.clamp
    for k, c in enumerate(cores):
        stuck = np.flatnonzero(clamp[c])
        assert np.array_equal(spins[0, k, stuck], clamp[c, stuck])
    # with readout flips the stuck spins still read their value most of the time
    noisy = EmulatedChip(spec.replace(readout_flip_prob=0.05), probe=False)
    spins, _ = noisy.anneal_batch(h, J, num_reads=400, seed=3)
    agree = [spins[0, k, np.flatnonzero(clamp[c])] == clamp[c, np.flatnonzero(clamp[c])]
             for k, c in enumerate(noisy.health.last_cores[0])]
    assert 0.9 < np.mean(agree) < 1.0


def test_dead_core_answers_garbage_without_the_probe():
    spec = CLEAN.replace(dead_cores=1, seed=2)
    chip = EmulatedChip(spec, probe=False)
    dead = chip.faults.dead_cores[0]
    h, J = _forcing(40)
    spins, energies = chip.anneal_batch(h, J, num_reads=16, seed=0)
    for k, c in enumerate(chip.health.last_cores[0]):  # a healthy core finds the forced state (rare misses aside)
        assert (0.2 < (spins[0, k] == 1).mean() < 0.8) == (c == dead)
    # energies are the programmed ones of what was read
    assert np.allclose(energies[0], IsingModel(h[0], J[0]).energy(spins[0]))


# ------------------------------------------------------------------ probe, quarantine, placement
@pytest.mark.parametrize("flip", [0.0, 0.01])
def test_probe_quarantines_dead_cores_and_finds_stuck_spins(flip):
    spec = ChipSpec(dead_cores=2, stuck_spins=3, readout_flip_prob=flip, seed=5)
    chip = EmulatedChip(spec, seed=0)
    health = chip.health
    assert np.array_equal(health.quarantined, chip.faults.dead)
    assert all("health probe" in r for r in health.reasons.values())
    ok = ~chip.faults.dead
    assert np.array_equal(health.known_stuck[ok], chip.faults.clamp[ok])
    assert chip.usable_spins == 42
    probe = 2 * spec.n_cores * PROBE_READS
    assert chip.ledger.probe_calls == chip.ledger.physical_calls == health.counts["probe_calls"] == probe
    summary = health.summary()
    assert sorted(summary["quarantined"]) == chip.faults.dead_cores and len(summary["healthy"]) == 6


def test_work_goes_to_healthy_cores_and_around_stuck_spins():
    spec = CLEAN.replace(dead_cores=1, stuck_spins=4, seed=3)
    h, J = _forcing(41, value=1)
    healthy = EmulatedChip(spec, seed=0)
    spins, _ = healthy.anneal_batch(h, J, num_reads=32, seed=1)
    # no garbage and no stuck spin (41 spins fit the 41 good ones): only rare anneal misses
    assert (spins != 1).sum(axis=2).max() <= 2 and (spins != 1).mean() < 0.01
    assert healthy.last_call.physical_calls == 32 and healthy.last_call.batches == math.ceil(32 / 7)
    raw = EmulatedChip(spec, seed=0, probe=False)
    bad = (raw.anneal_batch(h, J, num_reads=32, seed=1)[0] != 1).sum(axis=2)[0]
    cores = raw.health.last_cores[0]
    against = np.array([(raw.faults.clamp[c, :41] == -1).sum() for c in cores])  # stuck against the field
    assert (bad >= against).all() and against.max() > 0
    assert (bad[raw.faults.dead[cores]] > 5).all()


def test_batches_are_counted_over_healthy_cores():
    chip = EmulatedChip(CLEAN.replace(dead_cores=4, seed=1), seed=0)
    assert len(chip.health.healthy) == 4
    h, J = _random_program(10, B=8)
    chip.anneal_batch(h, J, num_reads=1, seed=0)
    assert chip.last_call.physical_calls == 8 and chip.last_call.batches == 2


def test_timeouts_are_detected_charged_and_redispatched():
    spec = CLEAN.replace(dead_cores=1, dead_core_mode="timeout", seed=6)
    raw = EmulatedChip(spec, probe=False)
    dead = raw.faults.dead_cores[0]
    h, J = _forcing(20)
    spins, _ = raw.anneal_batch(h, J, num_reads=16, seed=2)
    assert (spins != 1).mean() < 0.01  # every read answered (rare anneal misses aside)
    assert raw.health.quarantined[dead] and raw.health.reasons[dead] == "timed out"
    assert raw.last_call.retries == 2 and raw.last_call.physical_calls == 18  # 2 timed-out calls charged
    probed = EmulatedChip(spec)
    assert probed.health.reasons == {dead: "timed out in the health probe"}
    probed.anneal_batch(h, J, num_reads=16, seed=2)
    assert probed.last_call.retries == 0 and probed.last_call.physical_calls == 16


# ------------------------------------------------------------------ write errors and retries
def test_program_errors_are_retried_and_counted_deterministically():
    spec = CLEAN.replace(program_error_prob=0.3, max_retries=10, seed=9)
    h, J = _forcing(30)
    a, b = EmulatedChip(spec, seed=0), EmulatedChip(spec, seed=0)
    before = a.health.counts["write_errors"]
    sa, ea = a.anneal_batch(np.repeat(h, 6, 0), np.repeat(J, 6, 0), num_reads=4, seed=11)
    sb, eb = b.anneal_batch(np.repeat(h, 6, 0), np.repeat(J, 6, 0), num_reads=4, seed=11)
    assert np.array_equal(sa, sb) and np.array_equal(ea, eb) and _same_ledger(a.last_call, b.last_call)
    assert (sa != 1).mean() < 0.01
    call = a.last_call
    assert call.retries > 0 and call.physical_calls == 24 + call.retries
    assert a.health.counts["write_errors"] - before == call.retries == a.health.counts["retries"]
    assert math.isclose(call.energy_j, call.physical_calls * spec.energy_per_call_j)


def test_retry_budget_exhausted_raises_and_charges():
    spec = CLEAN.replace(program_error_prob=1.0, max_retries=2)
    chip = EmulatedChip(spec, seed=0)
    h, J = _random_program(10, B=2)
    probe = chip.ledger.physical_calls
    with pytest.raises(ChipUnavailableError, match="max_retries = 2"):
        chip.anneal_batch(h, J, num_reads=3, seed=0)
    assert chip.last_call.physical_calls == 6 * 3 and chip.last_call.retries == 12
    assert chip.ledger.physical_calls == probe + 18
    metered = MeteredSolver(chip)
    with pytest.raises(ChipUnavailableError):
        metered.anneal_batch(h, J, num_reads=3, seed=0)
    assert metered.charged.physical_calls == 18  # what the failed call spent is charged


def test_all_cores_dead_is_unavailable():
    chip = EmulatedChip(ChipSpec(dead_cores=8), seed=0)
    assert chip.health.healthy.size == 0
    with pytest.raises(ChipUnavailableError, match="every core is quarantined"):
        chip.anneal_batch(*_random_program(5), num_reads=1, seed=0)
    assert chip.last_call.physical_calls == 0


def test_faulty_chip_refuses_kernel_args_and_still_samples_bqms():
    chip = EmulatedChip(ChipSpec(stuck_spins=1, dead_cores=1), seed=0)
    with pytest.raises(RuntimeError, match="fault-tolerant"):
        chip.kernel_args()
    bqm = IsingModel([1, -1, 0], [[0, -2, 1], [0, 0, 3], [0, 0, 0]], 0.5).to_bqm()
    ss = chip.sample(bqm, num_reads=4, seed=1)
    dimod.testing.assert_sampleset_energies(ss, bqm)
    assert ss.info["ledger"]["physical_calls"] == 4


def test_same_seed_same_faulty_answers():
    spec = ChipSpec(dead_cores=1, stuck_spins=2, program_error_prob=0.1, readout_flip_prob=0.01, seed=3)
    h, J = _random_program(25, B=5)
    runs = []
    for _ in range(2):
        chip = EmulatedChip(spec, seed=8)
        runs.append([chip.anneal_batch(h, J, num_reads=3) for _ in range(3)] + [chip.health.summary()])
    for (sa, ea), (sb, eb) in zip(runs[0][:3], runs[1][:3]):
        assert np.array_equal(sa, sb) and np.array_equal(ea, eb)
    assert runs[0][3] == runs[1][3]


# ------------------------------------------------------------------ logical solver on the chip's cores
def test_logical_solver_shares_the_chip_health():
    spec = CLEAN.replace(program_error_prob=0.3, stuck_spins=2, dead_cores=1, max_retries=12, seed=2)
    chip = EmulatedChip(spec, seed=0)
    solver = LogicalIsingSolver(spec=spec, ledger=chip.ledger, health=chip.health)
    with pytest.raises(RuntimeError, match="fault-tolerant"):
        solver.kernel_args(9)
    h, J = _forcing(12)
    spins = solver.solve_stack(np.repeat(h, 4, 0), J[0], num_reads=2, seed=5)
    assert (spins == 1).all()
    assert solver.last_call.logical_calls == 8 + solver.last_call.retries and solver.last_call.physical_calls == 0
    res = solver.solve_many([IsingModel(h[0], J[0]), IsingModel(h[0, :5], J[0, :5, :5])], num_reads=2, seed=1)
    assert all((r.spins == 1).all() for r in res)
    # a 45-spin program meets the stuck spins (the last two logical spins), held through the search
    hb, Jb = _forcing(45)
    big = solver.solve_stack(hb, Jb[0], num_reads=8, seed=0)
    cores = chip.health.last_cores[0]
    assert (big[0, :, :43] == 1).all() and np.array_equal(big[0, :, 43:], chip.health.clamp[cores, 43:])
    dead = EmulatedChip(ChipSpec(dead_cores=8), seed=0)
    with pytest.raises(ChipUnavailableError):
        LogicalIsingSolver(spec=dead.spec, health=dead.health).solve_stack(h, J[0], num_reads=1, seed=0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-(2**63), 2**64 - 1), min_size=1, max_size=6))
def test_mix_of_scalars_is_the_array_hash(parts):
    """Scalar parts take a pure-integer path: the same bits as the numpy path of one-element arrays."""
    from ising_backend.faults.model import mix

    arrays = [np.array([p], dtype=np.uint64 if p >= 2**63 else np.int64) for p in parts]
    assert int(mix(*parts)) == int(mix(*arrays)[0])


def _splitmix_oracle(x: int) -> int:
    m = (1 << 64) - 1
    z = (x + 0x9E3779B97F4A7C15) & m
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & m
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & m
    return z ^ (z >> 31)


def _mix_oracle(*parts: int) -> int:
    key = 0
    for p in parts:
        key = _splitmix_oracle(key ^ (p & ((1 << 64) - 1)))
    return key


def test_fault_keys_are_one_splitmix64_round_per_part_for_scalars_and_arrays():
    from ising_backend.faults.model import mix

    rng = np.random.default_rng(3)
    for _ in range(100):
        parts = [int(rng.integers(0, 2**62)), int(rng.integers(-5, 5)), 2**64 - 1, int(rng.integers(0, 2**63))]
        assert int(mix(*parts)) == _mix_oracle(*parts)
    cores, reads = np.arange(4)[:, None], np.arange(3)[None, :]
    got = mix(2, 9, cores, np.uint64(2**63 + 5), reads)
    assert got.shape == (4, 3) and got.dtype == np.uint64
    for c in range(4):
        for r in range(3):
            assert int(got[c, r]) == _mix_oracle(2, 9, c, 2**63 + 5, r)
