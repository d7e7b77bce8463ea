"""A ``numpy.random.Generator`` handed to compiled code by address (a 4-word ``uint64`` handle).

numba unboxes a Generator argument anew on every call: it types the object, builds or reads its
bit generator's ``ctypes`` interface and casts three function pointers (~5 us a call, the
largest item in calling a compiled planning loop).  :func:`rng_handle` reads the same addresses
from numpy's C interface instead (the ``bitgen_t`` behind ``BitGenerator.capsule``: state,
``next_uint64``, ``next_uint32``, ``next_double``), once per Generator (~1 us);
:func:`as_generator` (compiled code only) turns the handle back into numba's Generator: the same
state and the same functions, so its draws are the Generator's own, advanced in place, bit for
bit what passing the Generator gives.

Contract: the caller keeps the Generator alive while compiled code uses its handle (a handle
does not own it); :func:`as_generator` also accepts a Generator itself, so a kernel taking
``rng`` works with either.
"""

from __future__ import annotations

import ctypes

import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic, overload

__all__ = ["rng_handle", "as_generator"]

#: ``PyCapsule_GetPointer`` with its own prototype (``ctypes.pythonapi``'s shared one is left alone)
_capsule_pointer = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.py_object, ctypes.c_char_p)(
    ("PyCapsule_GetPointer", ctypes.pythonapi))

_last: tuple = (None, None)  # (Generator, handle) of the last call: one plan hands one Generator to every layer


def rng_handle(rng: np.random.Generator) -> np.ndarray:
    """``uint64[4]``: the addresses of ``rng``'s bit-generator state and of its ``next_uint64``,
    ``next_uint32`` and ``next_double`` functions (memoised for the last Generator)."""
    global _last
    cached = _last
    if cached[0] is rng:
        return cached[1]
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    bitgen = _capsule_pointer(rng.bit_generator.capsule, b"BitGenerator")  # numpy's bitgen_t *
    handle = np.array((ctypes.c_uint64 * 4).from_address(bitgen), dtype=np.uint64)
    handle.setflags(write=False)
    _last = (rng, handle)
    return handle


def as_generator(rng):
    """The Generator of ``rng`` (a Generator, or a :func:`rng_handle` in compiled code)."""
    if isinstance(rng, np.random.Generator):
        return rng
    raise TypeError("a generator handle is only usable in compiled code; pass the numpy Generator")


_GENERATOR = types.NumPyRandomGeneratorType("generator")
_BIT_GENERATOR = types.NumPyRandomBitGeneratorType("bit_generator")


@intrinsic
def _generator_at(typingctx, handle):
    """numba's Generator struct over the addresses in ``handle`` (no parent object, no meminfo:
    references to it cost nothing and keep nothing alive)."""

    def codegen(context, builder, sig, args):
        data = context.make_array(sig.args[0])(context, builder, args[0]).data
        word = [builder.load(cgutils.gep(builder, data, i)) for i in range(4)]
        bit = cgutils.create_struct_proxy(_BIT_GENERATOR)(context, builder)  # zero-filled
        bit.state = word[0]
        bit.fnptr_next_uint64 = word[1]
        bit.fnptr_next_uint32 = word[2]
        bit.fnptr_next_double = word[3]
        gen = cgutils.create_struct_proxy(_GENERATOR)(context, builder)
        gen.bit_generator = bit._getvalue()
        return gen._getvalue()

    return _GENERATOR(handle), codegen


@overload(as_generator)
def _as_generator(rng):
    if isinstance(rng, types.NumPyRandomGeneratorType):
        return lambda rng: rng
    if isinstance(rng, types.Array) and rng.dtype == types.uint64 and rng.ndim == 1:
        return lambda rng: _generator_at(rng)
    return None
