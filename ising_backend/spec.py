"""The chip specification: hardware limits, accounting numbers, emulation knobs and the fault model.

Contract: :class:`ChipSpec` defaults are the paper's (sections 3 and 6.1: 45 all-to-all spins per core,
integer ``h`` and ``J`` in ``[-7, +7]``, 8 cores, 50 us and 0.45 uJ per solve); every field can be
changed for "what if" studies.  The emulation knobs are our choices; the fault fields are off by
default.  ``noise_free()`` and ``fault_free()`` switch the noise knobs and the fault model off.
Design notes: docs/design/emulated_chip.md (knobs), docs/design/faults.md (fault model).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np

__all__ = ["ChipSpec", "SCHEDULES", "DEAD_CORE_MODES"]

SCHEDULES = ("geometric", "linear")
DEAD_CORE_MODES = ("garbage", "timeout")


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
    dead_cores: int = 0
    dead_core_mode: str = "garbage"
    stuck_spins: int = 0
    program_error_prob: float = 0.0
    max_retries: int = 3

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
        for name, hi, what in (("dead_cores", self.n_cores, "n_cores"), ("stuck_spins", self.n_spins, "n_spins"),
                               ("max_retries", None, None)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0 or (hi is not None and v > hi):
                limit = f"an integer in [0, {what} = {hi}]" if hi is not None else "an integer >= 0"
                bad(f"{name} = {v!r} must be {limit}")
            object.__setattr__(self, name, int(v))
        if self.dead_core_mode not in DEAD_CORE_MODES:
            bad(f"dead_core_mode = {self.dead_core_mode!r} not in {DEAD_CORE_MODES}")
        if not (0 <= self.program_error_prob <= 1):
            bad(f"program_error_prob = {self.program_error_prob!r} must be in [0, 1]")

    @classmethod
    def from_options(cls, items, base: "ChipSpec | None" = None) -> "ChipSpec":
        """A spec from ``(key, value)`` pairs and/or paths of JSON files holding one object of fields, applied in
        order on ``base`` (default ``ChipSpec()``).  The command line splits its ``KEY=VALUE`` items into pairs
        (``agents.keyvalues``, the one splitter); this reads the values.

        Values: integers and floats as usual, as numbers or text; a range (``h_range``, ``j_range``) as ``m``
        (meaning ``(-m, m)``) or ``lo,hi`` (or a pair); ``beta_range`` as ``hot,cold`` or ``none``.  A JSON file is
        data only (parsed with :mod:`json`, at most 64 KiB).  An unknown field or a bad value raises ``ValueError``
        naming it and listing the valid fields.
        """
        spec = cls() if base is None else base
        for item in items:
            if isinstance(item, tuple) and len(item) == 2:
                key, value = item
                spec = spec._with(str(key), value, where=f"chip option {key}={value!r}")
            elif isinstance(item, (str, Path)):
                for key, value in _read_spec_file(item).items():
                    spec = spec._with(key, value, where=f"{item}: field {key!r}")
            else:
                raise ValueError(f"chip option {item!r} must be a (key, value) pair or a JSON file path")
        return spec

    def _with(self, key: str, value, where: str) -> "ChipSpec":
        names = [f.name for f in fields(self)]
        if key not in names:
            raise ValueError(f"{where}: unknown chip field {key!r}; valid fields: {', '.join(names)}")
        try:
            parsed = _parse_field(key, value)
            return replace(self, **{key: parsed})
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None

    @property
    def n_cores(self) -> int:
        """Parallel solver cores (chips x cores per chip): programs per batch."""
        return self.n_chips * self.cores_per_chip

    @property
    def energy_per_call_j(self) -> float:
        """Accelerator energy of one call: power x solve time (0.45 uJ by default)."""
        return self.power_w * self.solve_time_s

    @property
    def coefficient_limits(self) -> tuple[int, int]:
        """``(Lh, Lj)``: the largest magnitude every field / coupling may take (the symmetric part
        of ``h_range`` / ``j_range``), the quantizers' scale targets."""
        return tuple(min(-int(r[0]), int(r[1])) for r in (self.h_range, self.j_range))

    @property
    def faulty(self) -> bool:
        """Whether the fault model is on (dead cores, stuck spins or program write errors)."""
        return bool(self.dead_cores or self.stuck_spins or self.program_error_prob > 0)

    def noise_free(self) -> "ChipSpec":
        """This spec with coupling mismatch and readout flips switched off."""
        return replace(self, coupling_mismatch=0.0, readout_flip_prob=0.0)

    def fault_free(self) -> "ChipSpec":
        """This spec with dead cores, stuck spins and program write errors switched off."""
        return replace(self, dead_cores=0, stuck_spins=0, program_error_prob=0.0)

    def replace(self, **changes) -> "ChipSpec":
        return replace(self, **changes)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["n_cores"] = self.n_cores
        d["energy_per_call_j"] = self.energy_per_call_j
        return d


_INT_FIELDS = ("n_spins", "n_chips", "cores_per_chip", "sweeps", "seed", "dead_cores", "stuck_spins", "max_retries")
_FLOAT_FIELDS = ("solve_time_s", "power_w", "coupling_mismatch", "readout_flip_prob", "program_error_prob")
_MAX_SPEC_FILE = 64 * 1024


def _number(text, kind, key):
    if isinstance(text, bool):
        raise ValueError(f"{key} = {text!r} must be {'an integer' if kind is int else 'a number'}")
    if kind is int:
        if isinstance(text, (int, np.integer)):
            return int(text)
        if isinstance(text, str) and text.strip().lstrip("+-").isdigit():
            return int(text)
        raise ValueError(f"{key} = {text!r} must be an integer")
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"{key} = {text!r} must be a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{key} = {text!r} must be finite")
    return v


def _parse_field(key: str, value):
    """One field's value from a command-line string or a JSON value."""
    if key in _INT_FIELDS:
        return _number(value, int, key)
    if key in _FLOAT_FIELDS:
        return _number(value, float, key)
    if key in ("h_range", "j_range"):
        parts = value if isinstance(value, (list, tuple)) else str(value).split(",")
        nums = [_number(p, int, key) for p in parts]
        if len(nums) == 1:
            if nums[0] < 1:
                raise ValueError(f"{key} = {value!r}: a single value m means (-m, m) and must be >= 1")
            return (-nums[0], nums[0])
        if len(nums) != 2:
            raise ValueError(f"{key} = {value!r} must be m or lo,hi")
        return tuple(nums)
    if key == "beta_range":
        if value is None or str(value).strip().lower() == "none":
            return None
        parts = value if isinstance(value, (list, tuple)) else str(value).split(",")
        nums = [_number(p, float, key) for p in parts]
        if len(nums) != 2:
            raise ValueError(f"{key} = {value!r} must be hot,cold or none")
        return tuple(nums)
    if key in ("schedule", "dead_core_mode"):
        return str(value)
    raise ValueError(f"unknown chip field {key!r}")  # pragma: no cover - guarded by _with


def _read_spec_file(path) -> dict:
    p = Path(path)
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise ValueError(f"chip option {str(path)!r} is neither KEY=VALUE nor a readable JSON file ({exc})") from None
    if size > _MAX_SPEC_FILE:
        raise ValueError(f"{path}: {size} bytes; a chip spec file may hold at most {_MAX_SPEC_FILE} bytes")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a chip spec file holds one JSON object of fields, got {type(data).__name__}")
    return data
