"""Tables from the native module as numpy arrays, and the base of every result object."""

from __future__ import annotations

import dataclasses
from typing import Any, Dict, Tuple

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
        return all(
            same(getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self)
        )


def same(a: Any, b: Any) -> bool:
    """Equality by value through dicts, lists and tuples, arrays element by element (NaN
    equal to NaN)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return bool(a == b)


@dataclasses.dataclass(eq=False)
class TimeSeries(Result):
    """Samples in time: ``t`` (s), ``states`` (one row per sample, columns
    ``state_names``) and ``inputs`` (the inputs held from each sample on, columns
    ``input_names``)."""

    t: np.ndarray
    states: np.ndarray
    inputs: np.ndarray

    state_names: Tuple[str, ...] = ()
    input_names: Tuple[str, ...] = ()

    def column(self, name: str) -> np.ndarray:
        """One column by name: ``"t"``, a state or an input."""
        if name == "t":
            return self.t
        if name in self.state_names:
            return self.states[:, self.state_names.index(name)]
        if name in self.input_names:
            return self.inputs[:, self.input_names.index(name)]
        raise KeyError(name)

    def to_pandas(self):
        """The table as a pandas DataFrame (columns ``t``, the states, the inputs)."""
        import pandas as pd

        names = ("t",) + tuple(self.state_names) + tuple(self.input_names)
        return pd.DataFrame({n: self.column(n) for n in names})


def series(d: Dict[str, Any], state_names, input_names) -> Dict[str, Any]:
    """The fields of a :class:`TimeSeries` from a native table."""
    cols = table(d)
    return {
        "t": cols["t"],
        "states": stack(cols, state_names),
        "inputs": stack(cols, input_names),
    }
