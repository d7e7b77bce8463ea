"""Portfolio runner: batched dispatch, decode/filter/score on the original objective, statistics."""

import itertools

import numpy as np
import pytest

from ising_backend import (
    BranchMapping,
    ChipSpec,
    EmulatedChip,
    IdentityMapping,
    IsingModel,
    LogicalIsingSolver,
    MergeMapping,
    PortfolioStats,
    QuantizeMapping,
    SaturateMapping,
    merge_portfolio,
    quantize_portfolio,
    run_portfolio,
    run_portfolio_batch,
)


def _ground(m):
    S = np.array(list(itertools.product([-1, 1], repeat=m.n)))
    return m.energy(S).min()


def _models(seed, k, n, scale):
    rng = np.random.default_rng(seed)
    return [IsingModel(rng.normal(0, scale, n), np.triu(rng.normal(0, scale, (n, n)), 1)) for _ in range(k)]


def test_quantize_portfolio_scores_on_original_objective_in_one_call():
    models = _models(0, 30, 10, 3.0)
    chip = EmulatedChip(ChipSpec().noise_free(), seed=0)
    res = run_portfolio_batch(models, quantize_portfolio(), chip, num_reads=4, seed=1)
    assert chip.ledger.physical_calls == 30 * 4 * 4 and chip.ledger.batches == 60  # one dispatch
    stats = PortfolioStats()
    for m, r in zip(models, res):
        stats.add(r)
        assert r.success and r.calls == 16
        assert r.best_score == pytest.approx(m.energy(r.best_spins))  # original, unquantized energy
        assert r.best_score == min(o.best_score for o in r.outcomes.values())
        assert sum(o.win for o in r.outcomes.values()) == pytest.approx(1.0)
    hits = np.mean([r.best_score == pytest.approx(_ground(m)) for m, r in zip(models, res)])
    assert hits >= 0.8
    rows = {row["mapping"]: row for row in stats.table()}
    assert set(rows) == {"linear", "clip95", "rank", "sqrt"}
    assert sum(row["win_share"] for row in rows.values()) == pytest.approx(1.0)
    assert all(row["valid_rate"] == 1.0 for row in rows.values())
    assert sum(row["candidate_share"] for row in rows.values()) == pytest.approx(1.0)


def test_decoder_validity_filter_and_failed_mappings():
    models = _models(1, 10, 6, 20.0)
    chip = EmulatedChip(ChipSpec(n_spins=8).noise_free(), seed=0)

    def decode(s):
        return None if s[0] < 0 else tuple(int(v) for v in s)  # only s0 = +1 decodes

    def objective(c):
        return float(sum(c))

    res = run_portfolio_batch(models, merge_portfolio() + [SaturateMapping(1.0)], chip, decode=decode,
                              is_valid=lambda c: c[1] == 1, objective=objective, num_reads=6, seed=2)
    stats = PortfolioStats()
    for r in res:
        stats.add(r)
        if r.success:
            assert r.best[0] == 1 and r.best[1] == 1 and r.best_score == sum(r.best)
        for name, o in r.outcomes.items():
            assert o.valid <= o.reads
            if o.error is not None:  # the 8-spin chip cannot hold every merge
                assert "chip spins are used" in o.error and o.reads == 0
    rows = {row["mapping"]: row for row in stats.table()}
    assert rows["saturate"]["failed_maps"] == 0
    assert any(row["failed_maps"] > 0 for row in rows.values())
    assert all(0.0 <= row["valid_rate"] < 1.0 for row in rows.values())


def test_packing_saves_calls_and_keeps_results_valid():
    models = _models(2, 12, 8, 2.0)
    a = EmulatedChip(ChipSpec().noise_free(), seed=0)
    b = EmulatedChip(ChipSpec().noise_free(), seed=0)
    ra = run_portfolio_batch(models, quantize_portfolio(), a, num_reads=2, seed=3)
    rb = run_portfolio_batch(models, quantize_portfolio(), b, num_reads=2, seed=3, pack=True)
    assert a.ledger.physical_calls == 12 * 4 * 2
    assert b.ledger.physical_calls == 2 * int(np.ceil(12 * 4 / 5))  # 5 blocks of 8 spins per 45-spin program
    for m, r in zip(models, rb):
        assert r.best_score == pytest.approx(m.energy(r.best_spins))
    assert np.mean([r.best_score <= s.best_score + 1e-9 for r, s in zip(rb, ra)]) >= 0.5


def test_branch_mapping_with_logical_solver_is_exact_and_counts_logical_calls():
    rng = np.random.default_rng(6)
    m = IsingModel(rng.normal(0, 30, 14), np.triu(rng.normal(0, 30, (14, 14)), 1))
    sol = LogicalIsingSolver(budget=11, seed=0)
    r = run_portfolio(m, [BranchMapping(), ], sol)
    assert r.outcomes["branch"].programs == 8
    assert r.best_score == pytest.approx(_ground(m))
    assert sol.ledger.logical_calls == 8 and sol.ledger.physical_calls == 0
    same = run_portfolio(m, [IdentityMapping()], LogicalIsingSolver(budget=14, seed=0))
    assert same.best_score == pytest.approx(r.best_score)


def test_portfolio_is_deterministic_and_validates_names():
    models = _models(3, 5, 7, 4.0)
    r1 = run_portfolio_batch(models, quantize_portfolio(), EmulatedChip(seed=1), num_reads=2, seed=9)
    r2 = run_portfolio_batch(models, quantize_portfolio(), EmulatedChip(seed=2), num_reads=2, seed=9)
    assert [r.best_score for r in r1] == [r.best_score for r in r2]
    with pytest.raises(ValueError, match="distinct"):
        run_portfolio(models[0], [QuantizeMapping("linear"), QuantizeMapping("linear")], EmulatedChip())
    with pytest.raises(ValueError, match="style"):
        MergeMapping("zigzag")
