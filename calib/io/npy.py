"""Reading ``.npy`` headers safely: dtype and shape are known, and checked, before any data
is read or any memory is allocated (used by the capture reader and the bundle loader)."""

from __future__ import annotations

import math
from typing import IO

import numpy as np

# The most bytes one array may hold: far above any projector grid's map (a 4K grid's
# float32 RGB map is 0.1 GB), far below what would exhaust a machine's memory.
MAX_ARRAY_BYTES = 2 << 30


def read_header(f: IO[bytes]) -> tuple[tuple[int, ...], np.dtype]:
    """(shape, dtype) of the ``.npy`` stream ``f``, leaving ``f`` at the start of the data.

    Raises ValueError (with the cause) for a damaged header, an object dtype (it would need
    pickle), Fortran order, a negative dimension or more than :data:`MAX_ARRAY_BYTES`.
    """
    try:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
        elif version in ((2, 0), (3, 0)):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise ValueError(f"unsupported .npy version {version}")
    except (EOFError, OSError, SyntaxError) as exc:
        raise ValueError(f"damaged .npy header ({exc})") from None
    if dtype.hasobject:
        raise ValueError("an object array, which would need pickle")
    if fortran:
        raise ValueError("Fortran-ordered, which viewcomp does not write")
    if any(not isinstance(n, int) or n < 0 for n in shape):
        raise ValueError(f"invalid shape {shape}")
    nbytes = math.prod(shape) * dtype.itemsize
    if nbytes > MAX_ARRAY_BYTES:
        raise ValueError(
            f"declares {dtype.str} {list(shape)}, {nbytes / 2**30:.1f} GiB, over the "
            f"{MAX_ARRAY_BYTES / 2**30:g} GiB limit"
        )
    return tuple(shape), dtype


def read_data(f: IO[bytes], shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    """The array body after :func:`read_header`: exactly ``prod(shape)`` items or ValueError."""
    count = math.prod(shape)
    data = f.read(count * dtype.itemsize)
    if len(data) != count * dtype.itemsize:
        raise ValueError(
            f"short: {len(data)} of the {count * dtype.itemsize} data bytes its header declares"
        )
    return np.frombuffer(data, dtype=dtype, count=count).reshape(shape).copy()
