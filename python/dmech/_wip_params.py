"""The WIP's model parameters: :class:`Params`, the keys of a parameter file."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Mapping, Optional, Union

from . import _native
from .errors import call

#: What every function's ``params`` takes: parameters, a dict of some keys, or a
#: parameter file's path.
ParamsLike = Union["Params", Mapping[str, float], str, os.PathLike]


class Params:
    """The WIP's model parameters (SI units), the keys of a parameter file.

    ``Params()`` is the default robot; ``Params.load(path)`` reads a parameter file (any
    subset of the keys; the rest keep their defaults), ``p.replace(m_b=0.3)`` changes keys,
    ``p.save(path)`` writes every key. Every constructor checks the values as
    ``wip --params`` does and raises :class:`BadInputError` naming a bad key.
    """

    __slots__ = ("_values",)

    def __init__(self, **values: float) -> None:
        text = json.dumps(values) if values else _native.wip_default_params()
        object.__setattr__(self, "_values", json.loads(call(_native.wip_check_params, text)))

    @classmethod
    def from_json(cls, text: str) -> "Params":
        """From the text of a parameter file."""
        p = cls.__new__(cls)
        object.__setattr__(p, "_values", json.loads(call(_native.wip_check_params, text)))
        return p

    @classmethod
    def load(cls, path: Union[str, os.PathLike]) -> "Params":
        """From a parameter file."""
        with open(path, encoding="utf-8") as f:
            return cls.from_json(f.read())

    def to_json(self) -> str:
        """The parameter file's text (every key)."""
        return json.dumps(self._values, indent=2) + "\n"

    def save(self, path: Union[str, os.PathLike]) -> None:
        """Write the parameter file."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.to_json())

    def replace(self, **changes: float) -> "Params":
        """A copy with some keys changed."""
        return Params(**{**self._values, **changes})

    def to_dict(self) -> Dict[str, float]:
        return dict(self._values)

    def __getattr__(self, key: str) -> float:
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(key) from None

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("Params is immutable: use replace()")

    def __getstate__(self):
        return self._values

    def __setstate__(self, values):
        object.__setattr__(self, "_values", values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Params) and self._values == other._values

    def __repr__(self) -> str:
        body = ", ".join(f"{k}={v!r}" for k, v in self._values.items())
        return f"Params({body})"


def params() -> Params:
    """The default parameters (``wip params``)."""
    return Params()


def params_json(p: Optional[ParamsLike]) -> Optional[str]:
    """A ``params`` argument as a parameter file's text (``None``: the defaults)."""
    if p is None:
        return None
    if isinstance(p, Params):
        return p.to_json()
    if isinstance(p, Mapping):
        return json.dumps(dict(p))
    return Params.load(p).to_json()
