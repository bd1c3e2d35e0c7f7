"""Tables from the native module as numpy arrays, and the base of every result object."""

from __future__ import annotations

import dataclasses
from typing import Any, Dict

import numpy as np


def table(d: Dict[str, Any]) -> Dict[str, np.ndarray]:
    """``{"columns": [...], "rows": n, "data": bytes}`` as ``{column: array}``."""
    columns = list(d["columns"])
    data = np.frombuffer(d["data"], dtype="<f8").reshape(d["rows"], len(columns))
    data = data.copy()  # own the memory (the bytes object may go)
    return {c: data[:, j] for j, c in enumerate(columns)}


def stack(columns: Dict[str, np.ndarray], names) -> np.ndarray:
    """The named columns side by side, one row per sample."""
    return np.column_stack([columns[n] for n in names]) if names else np.empty((0, 0))


class Result:
    """Behaviour every result shares: a readable ``repr``, equality by value (arrays
    compared element by element), and ``to_dict``."""

    def to_dict(self) -> Dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        for f in dataclasses.fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                if not np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True):
                    return False
            elif a != b:
                return False
        return True
