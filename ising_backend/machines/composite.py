"""A dimod composite that maps any binary quadratic model onto an integer-range Ising chip.

Contract: :class:`QuantizeComposite` samples a BQM on a strict child (the chip, or any sampler with
integer ``h_range`` / ``j_range`` and ``num_spins`` properties) through a quantization rule (one of
:data:`~ising_backend.mapping.quantize.QUANTIZE_RULES`, or ``"saturate"``).  Returned energies are the original
BQM's; a BQM larger than the child raises ``ValueError`` (nothing is truncated, merged or branched); an
empty BQM returns 0 rows without a chip call.  Design notes: docs/design/mapping_kernels.md.
"""

from __future__ import annotations

from collections.abc import Mapping

import dimod
import numpy as np

from ising_backend.ledger import CallLedger
from ising_backend.models import IsingModel, QuboModel
from ising_backend.mapping.quantize import QUANTIZE_RULES, QuantizeError, quantize, saturate

__all__ = ["COMPOSITE_RULES", "QuantizeComposite"]

COMPOSITE_RULES = QUANTIZE_RULES + ("saturate",)


def _check_rule(rule, scale) -> None:
    if rule not in COMPOSITE_RULES:
        raise QuantizeError(f"rule = {rule!r} not in {COMPOSITE_RULES}")
    if rule == "saturate":
        if scale is None:
            raise QuantizeError("rule = 'saturate' needs a fixed scale: pass scale=<positive number>")
        if isinstance(scale, bool) or not isinstance(scale, (int, float, np.integer, np.floating)) \
                or not (np.isfinite(scale) and scale > 0):
            raise QuantizeError(f"scale = {scale!r} must be a positive finite number")


class QuantizeComposite(dimod.ComposedSampler):
    """Sample any BQM on an integer-range Ising sampler through a quantization rule.

    Args:
        child: an :class:`~ising_backend.machines.chip.EmulatedChip` or any dimod sampler
            with ``properties["h_range"]``, ``["j_range"]`` (integer ``(low, high)``)
            and ``["num_spins"]``.
        rule: default rule, one of :data:`COMPOSITE_RULES`.
        keep_sign: for the ``quantize`` rules, a non-zero coefficient never rounds to 0.
        scale: the fixed factor of ``rule="saturate"`` (required for that rule).
        percentile: the clip point of ``clip95``.

    Example:
        >>> from ising_backend import EmulatedChip
        >>> sampler = QuantizeComposite(EmulatedChip(seed=0))
        >>> ss = sampler.sample_ising({"a": 0.3}, {("a", "b"): -12.5}, num_reads=4, seed=1)
        >>> float(ss.first.energy), ss.info["rule"], ss.info["ledger"]["physical_calls"]
        (-12.8, 'linear', 4)
    """

    def __init__(self, child: dimod.Sampler, rule: str = "linear", keep_sign: bool = True,
                 scale: float | None = None, percentile: float = 95.0):
        props = getattr(child, "properties", None)
        missing = [k for k in ("h_range", "j_range", "num_spins") if not isinstance(props, Mapping) or k not in props]
        if missing:
            raise ValueError(f"child {type(child).__name__} has no properties {missing}; QuantizeComposite needs "
                             "h_range, j_range and num_spins (e.g. an EmulatedChip)")
        num_spins = props["num_spins"]
        if isinstance(num_spins, bool) or not isinstance(num_spins, (int, np.integer)) or num_spins < 0:
            raise ValueError(f"child properties['num_spins'] = {num_spins!r} must be a non-negative integer")
        _check_rule(rule, scale)
        # fail now, not on the first call, on ranges the rules cannot use
        probe = IsingModel(np.ones(1), np.zeros((1, 1)))
        if rule == "saturate":
            saturate(probe, scale, props["h_range"], props["j_range"])
        else:
            quantize(probe, QUANTIZE_RULES[0], props["h_range"], props["j_range"], percentile=percentile)
        self._children = [child]
        self.rule = rule
        self.keep_sign = bool(keep_sign)
        self.scale = scale
        self.percentile = percentile

    @property
    def children(self) -> list:
        return self._children

    @property
    def parameters(self) -> dict:
        params = {k: list(v) for k, v in self.child.parameters.items()}
        params.setdefault("num_reads", [])
        params.setdefault("seed", [])
        params.update(rule=["rules"], scale=[])
        return params

    @property
    def properties(self) -> dict:
        return {"child_properties": dict(self.child.properties), "rules": list(COMPOSITE_RULES)}

    def quantized(self, bqm: dimod.BinaryQuadraticModel, rule: str | None = None,
                  scale: float | None = None) -> tuple[IsingModel, list]:
        """The integer program the child receives for ``bqm`` (unlabelled, offset 0) and the BQM's
        variables in program order.

        Raises:
            ValueError: more variables than the child's ``num_spins``; a bad rule or scale
                (:class:`~ising_backend.mapping.quantize.QuantizeError`); a non-finite bias
                (:class:`~ising_backend.models.ModelError`).
        """
        rule = self.rule if rule is None else rule
        scale = self.scale if scale is None else scale
        _check_rule(rule, scale)
        props = self.child.properties
        variables = list(bqm.variables)
        limit = int(props["num_spins"])
        if len(variables) > limit:
            raise ValueError(
                f"BQM has {len(variables)} variables; the child has {limit} spins (properties['num_spins']). "
                "QuantizeComposite neither truncates nor merges: use a larger chip spec, or the merge / "
                "branching mappings of ising_backend"
            )
        lin, (row, col, quad), offset = bqm.to_numpy_vectors(variables)
        n = len(variables)
        upper = np.zeros((n, n))
        np.add.at(upper, (np.minimum(row, col), np.maximum(row, col)), np.asarray(quad, dtype=np.float64))
        lin = np.asarray(lin, dtype=np.float64)
        if bqm.vartype is dimod.BINARY:
            model = QuboModel(lin, upper, float(offset)).to_ising()  # exact: x = (1 + s) / 2
        else:
            model = IsingModel(lin, upper, float(offset))
        if rule == "saturate":
            prog = saturate(model, scale, props["h_range"], props["j_range"])
        else:
            prog = quantize(model, rule, props["h_range"], props["j_range"], keep_sign=self.keep_sign,
                            percentile=self.percentile)
        return IsingModel.trusted(prog.h, prog.J, 0.0, None), variables

    def sample(self, bqm: dimod.BinaryQuadraticModel, *, rule: str | None = None, scale: float | None = None,
               num_reads: int | None = None, seed: int | None = None, **parameters) -> dimod.SampleSet:
        """Quantize ``bqm`` into the child's ranges, sample it there, re-score on ``bqm``.

        Args:
            bqm: any binary quadratic model (SPIN or BINARY, any hashable labels).
            rule, scale: override the composite's rule (and ``saturate``'s scale) for this call.
            num_reads, seed: forwarded to the child when given (the chip's defaults otherwise).
            **parameters: other child parameters.

        Returns:
            A SampleSet in ``bqm``'s vartype and labels whose ``energy`` is ``bqm``'s energy;
            ``program_energy`` holds the child's energy of the integer program.
        """
        rule = self.rule if rule is None else rule
        scale = self.scale if scale is None else scale
        program, variables = self.quantized(bqm, rule, scale)
        info = {"rule": rule, "keep_sign": self.keep_sign, "scale": scale if rule == "saturate" else None}
        if not variables:
            return dimod.SampleSet.from_samples(([], []), bqm.vartype, energy=[],
                                                info={"ledger": CallLedger().to_dict(), **info})
        if num_reads is not None:
            parameters["num_reads"] = num_reads
        if seed is not None:
            parameters["seed"] = seed
        child_ss = self.child.sample(program.to_bqm(), **parameters)
        if child_ss.vartype is not dimod.SPIN:
            child_ss = child_ss.change_vartype(dimod.SPIN, inplace=False)
        n = len(variables)
        try:
            cols = [child_ss.variables.index(k) for k in range(n)]
        except ValueError:
            raise ValueError(f"child returned variables {list(child_ss.variables)}; expected 0 .. {n - 1}") from None
        spins = np.asarray(child_ss.record.sample)[:, cols].astype(np.int8)
        samples = ((spins + 1) // 2).astype(np.int8) if bqm.vartype is dimod.BINARY else spins
        return dimod.SampleSet.from_samples_bqm(
            (samples, variables), bqm,
            num_occurrences=child_ss.record.num_occurrences,
            program_energy=np.asarray(child_ss.record.energy, dtype=np.float64),
            info={**child_ss.info, **info},
        )
