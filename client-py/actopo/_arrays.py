"""Arrays on the wire: raw little-endian bytes with a dtype and a shape."""

from __future__ import annotations

from typing import Any

import numpy as np

from actopo._errors import InvalidArgumentError
from actopo._proto import pb

DTYPES: dict[Any, np.dtype[Any]] = {
    pb.DATA_TYPE_FLOAT32: np.dtype("<f4"),
    pb.DATA_TYPE_FLOAT64: np.dtype("<f8"),
    pb.DATA_TYPE_INT8: np.dtype("i1"),
    pb.DATA_TYPE_INT32: np.dtype("<i4"),
    pb.DATA_TYPE_INT64: np.dtype("<i8"),
    pb.DATA_TYPE_UINT8: np.dtype("u1"),
}
_CODES = {dtype.str: code for code, dtype in DTYPES.items()}


def dtype_of(code: int) -> np.dtype[Any]:
    """The numpy dtype of a DataType value."""
    try:
        return DTYPES[code]
    except KeyError:
        raise InvalidArgumentError(f"unknown DataType {code} in a server response") from None


def dtype_name(code: int) -> str:
    """'float32', 'int64', ... for a DataType value ('unspecified' for 0)."""
    return DTYPES[code].name if code in DTYPES else "unspecified"


def code_of(dtype: np.dtype[Any]) -> Any:
    """The DataType value of a numpy dtype (byte order ignored)."""
    return _CODES[np.dtype(dtype).newbyteorder("<").str]


def little_endian(values: np.ndarray, dtype: Any) -> np.ndarray:
    """`values` as a C-contiguous little-endian array of `dtype` (no copy when it already is)."""
    return np.ascontiguousarray(values, dtype=np.dtype(dtype).newbyteorder("<"))


def to_numpy(array: pb.Array) -> np.ndarray:
    """A read-only numpy view of an Array's bytes, in its shape."""
    values = np.frombuffer(array.data, dtype=dtype_of(array.dtype))
    return values.reshape(tuple(array.shape)) if len(array.shape) > 1 else values


def to_array(values: np.ndarray, name: str = "") -> pb.Array:
    """An Array message holding `values` (int32, int64, float32, float64, int8 or uint8)."""
    values = np.asarray(values)
    le = little_endian(values, values.dtype)
    return pb.Array(name=name, dtype=code_of(le.dtype), shape=list(le.shape), data=le.tobytes())
