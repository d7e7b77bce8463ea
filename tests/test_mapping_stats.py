"""One mapping statistics record for every Ising layer (``ising_backend.mapping_record``)."""

import numpy as np
import pytest

from agents.experiments.records import ExperimentResult
from agents.experiments.summary import mapping_table
from ising_backend import MAPPING_FIELDS, add_counts, mapping_record
from mrmt_env.generation import generate_world
from planners.ising.fleet.search import FleetConfig, IsingFleetSharing
from planners.ising.path.search import IsingPath
from planners.ising.sharing.search import IsingSharing
from planners.pipeline import make_pipeline
from planners.tours_classical import NearestNeighbourTour


def test_a_record_is_zeros_or_the_rows_in_field_order():
    assert mapping_record(["a", "b"]) == {c: dict.fromkeys(MAPPING_FIELDS, 0) for c in "ab"}
    rec = mapping_record(["a"], np.array([[1, 2, 3, 4, 5]]))
    assert rec == {"a": dict(zip(MAPPING_FIELDS, [1, 2, 3, 4, 5]))}
    assert all(type(v) is int for v in rec["a"].values())  # plain ints: summed by merge_stats, serialized as is


def test_rows_of_the_wrong_shape_are_refused_with_the_sizes():
    with pytest.raises(ValueError, match=r"1 x 5 .* got \[4\]"):
        mapping_record(["a"], [[1, 2, 3, 4]])
    with pytest.raises(ValueError, match=r"2 x 5 .* got \[5\]"):
        mapping_record(["a", "b"], [[1, 2, 3, 4, 5]])


def test_counts_add_into_existing_counters_only():
    rec = mapping_record(["a"])
    add_counts(rec["a"], programs=2, reads=np.int64(4))
    add_counts(rec["a"], programs=1)
    assert rec["a"]["programs"] == 3 and rec["a"]["reads"] == 4 and type(rec["a"]["reads"]) is int
    with pytest.raises(KeyError, match="read"):
        add_counts(rec["a"], read=1)  # a misspelt counter is not created


@pytest.mark.parametrize("preset", ["ising", "ising-paper"])
def test_every_layer_keeps_the_same_record(preset):
    plan = make_pipeline(preset).plan(generate_world(3, n_robots=3, n_targets=10), seed=0)
    assert plan.success
    mapping = plan.stats["mapping"]
    assert set(mapping) == ({"sharing", "tour"} if preset == "ising" else {"sharing", "tour", "path"})
    for layer, choices in mapping.items():
        for choice, counts in choices.items():
            assert tuple(counts) == MAPPING_FIELDS, (layer, choice)
            assert 0 <= counts["valid"] <= counts["reads"] and counts["programs"] <= counts["reads"]
    # the tour's decisions on the machine: a move-selection round or a one-hot model with a valid read
    assert sum(v["wins"] for v in mapping["tour"].values()) == plan.stats["valid_subproblems"] > 0
    # the plan's counters are the layers' own: the sharing's splits are not summed with the tour's
    assert sum(v["wins"] for v in mapping["sharing"].values()) == plan.stats["splits"] - plan.stats["trivial_splits"]


def test_the_path_counts_one_win_per_segment_the_chip_chose():
    world = generate_world(4, n_robots=1, n_targets=1)
    res = IsingPath().find_path(world, world.robots[0], world.targets[0], np.random.default_rng(0))
    assert res.success
    m, st = res.stats["mapping"]["path"], res.stats
    assert sum(v["wins"] for v in m.values()) == st["segments"] - st["direct_moves"]
    assert all(v["reads"] == v["programs"] * IsingPath().config.num_reads for v in m.values())


def test_the_sharing_counts_one_win_per_split_it_solved_on_the_chip():
    world = generate_world(5, n_robots=3, n_targets=10)
    sharing = IsingSharing()
    res = sharing.assign(world.distance_matrix, 3, NearestNeighbourTour(), np.random.default_rng(0))
    m, st = res.stats["mapping"]["sharing"], res.stats
    assert sum(v["wins"] for v in m.values()) == st["splits"] - st["trivial_splits"]
    assert all(v["reads"] == v["programs"] * sharing.config.reads for v in m.values())


@pytest.mark.parametrize("selection", ["chip", "greedy"])
def test_the_fleet_keeps_the_record_per_selection_rule(selection):
    world = generate_world(6, n_robots=4, n_targets=40)
    sharing = IsingFleetSharing(selection=selection, kicks=3)
    res = sharing.assign(world.distance_matrix, 4, None, np.random.default_rng(0))
    assert res.failure is None
    m, fleet = res.stats["mapping"]["fleet"], res.stats["fleet"]
    assert tuple(m) == sharing.config.chip_rules
    if selection == "chip":  # every chip read of the search is one rule's: the counts add up to the search's
        assert sum(v["reads"] for v in m.values()) == fleet["reads"] == res.compute.chip_calls > 0
        assert all(v["programs"] == fleet["rounds"] for v in m.values())
    else:  # the host rule selects: no program, no read, no win
        assert all(not any(v.values()) for v in m.values())


def test_a_rule_named_twice_is_refused():
    with pytest.raises(ValueError, match=r"chip_rules = \('rank', 'rank'\) names a rule twice"):
        FleetConfig(chip_rules=("rank", "rank"))


def test_table_5_reads_the_record():
    rec = {"path": mapping_record(["overload", "balanced"], [[2, 4, 3, 1, 0], [2, 4, 1, 3, 1]])}
    rows = [{"method": "ising", "mapping": rec}, {"method": "ising", "mapping": rec}, {"method": "bfs"}]
    table = {r["choice"]: r for r in mapping_table(ExperimentResult("path", rows, ("ising", "bfs")), None)}
    assert table["overload"]["candidates"] == 8 and table["overload"]["valid_rate_pct"] == pytest.approx(75.0)
    assert table["balanced"]["win_share_pct"] == pytest.approx(75.0)
    assert table["overload"]["candidate_share_pct"] == pytest.approx(50.0)
