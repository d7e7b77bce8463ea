"""Mapping and programs: numpy's summation order in compiled code (``numeric``), quantization (``quantize``),
spin merging (``merge``), spin-budget branching (``branching``), block batching (``blocks``), a QUBO stack to
packed programs (``stack``), the portfolio of mappings (``portfolio``) and its statistics (``mapping_stats``)."""
