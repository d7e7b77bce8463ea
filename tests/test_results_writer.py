"""benchmarks/_common.write_results_section: a rewritten section keeps what its author marked."""

from __future__ import annotations

from benchmark_modules import load

common = load("_common")


def test_a_rewrite_replaces_the_tables_and_keeps_the_marked_reading(tmp_path):
    path = tmp_path / "RESULTS.md"
    path.write_text("# Benchmark results\n\n## A\n\nold table\n\n" + common.KEEP_MARK + "\n\nReading: by hand.\n\n"
                    "### Sub by hand\n\nrows\n\n## B\n\nother\n")
    common.write_results_section("## A", "## A\n\nnew table\n", path)
    text = path.read_text()
    assert "old table" not in text and "new table" in text
    assert text.index("new table") < text.index(common.KEEP_MARK) < text.index("Reading: by hand.")
    assert "### Sub by hand\n\nrows" in text and text.endswith("## B\n\nother\n")
    common.write_results_section("## A", "## A\n\nnewer table\n", path)  # again: one mark, one reading
    text = path.read_text()
    assert text.count(common.KEEP_MARK) == 1 and text.count("Reading: by hand.") == 1 and "new table" not in text


def test_without_a_mark_the_section_is_replaced_whole_and_a_new_one_appended(tmp_path):
    path = tmp_path / "RESULTS.md"
    path.write_text("# Benchmark results\n\n## A\n\nold\n\n## B\n\nother\n")
    common.write_results_section("## A", "## A\n\nnew\n", path)
    common.write_results_section("## C", "## C\n\nthird\n", path)
    assert path.read_text() == "# Benchmark results\n\n## A\n\nnew\n\n## B\n\nother\n\n## C\n\nthird\n"
