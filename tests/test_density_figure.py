"""benchmarks/lorr_density_figure: issue 57's figure reads the measured tables of RESULTS.md by name."""

from __future__ import annotations

import pytest

from benchmark_modules import load

fig = load("lorr_density_figure")

TEXT = """## A section
| a | b |
|---|---:|
| x | 1 |

text between

| instance | seed 0 |
|---|---:|
| RANDOM-04 | 2,324 (89.9 %) |
| RANDOM-05 | **2,676** |

## Next
| instance | seed 0 |
|---|---:|
| RANDOM-04 | 1 |
"""


def test_tables_are_read_by_section_and_number():
    assert fig.section_table("## A section", TEXT) == [{"a": "x", "b": "1"}]
    rows = fig.section_table("## A section", TEXT, which=1)
    assert [(r["instance"], fig.number(r["seed 0"])) for r in rows] == [("RANDOM-04", 2324.0), ("RANDOM-05", 2676.0)]
    with pytest.raises(ValueError, match="has no table 3"):
        fig.section_table("## A section", TEXT, which=2)  # the next section's table is not this one's
    with pytest.raises(ValueError, match="no section '## Missing'"):
        fig.section_table("## Missing", TEXT)


def test_cells_of_several_numbers():
    assert fig.numbers("9.38 / 9.36 / 9.39") == [9.38, 9.36, 9.39]
    assert fig.numbers("8.5e-03 - 9.0e-03") == [8.5e-3, 9.0e-3]
    assert fig.numbers("0") == [0.0]
    with pytest.raises(ValueError, match="no number in table cell 'n/a'"):
        fig.number("n/a")


def test_the_figure_draws_from_the_results_file(tmp_path):
    out = tmp_path / "density.png"
    fig.main(["--out", str(out)])
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
