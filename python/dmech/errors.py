"""The exceptions dmech raises.

Every exception carries the command line's one-line message as its ``str``::

    DmechError                    every failure of dmech
    ├── BadInputError (ValueError)    a request or input refused before the run
    ├── NotSolvedError (RuntimeError) a plan that was not solved; ``.result`` holds it
    │   └── InfeasibleError           ... because no feasible point is near
    └── RunError (RuntimeError)       a run that started and failed (a simulation step)
"""

from __future__ import annotations

from typing import Any, Callable, TypeVar

from . import _native

__all__ = [
    "DmechError",
    "BadInputError",
    "NotSolvedError",
    "InfeasibleError",
    "RunError",
]


class DmechError(Exception):
    """Every failure of dmech."""


class BadInputError(DmechError, ValueError):
    """A request or an input refused before anything ran (a bad waypoint set, a step out
    of range, a parameter file with an unknown key, ...)."""


class NotSolvedError(DmechError, RuntimeError):
    """A plan that was not solved (iteration limit, solver failure). The unsolved plan is
    ``.result``, as the command line still writes its files."""

    def __init__(self, message: str, result: Any = None) -> None:
        super().__init__(message)
        self.result = result

    def __reduce__(self):  # keep ``result`` through pickling
        return (type(self), (str(self), self.result))


class InfeasibleError(NotSolvedError):
    """A plan whose solver found no feasible point near (waypoints or end state out of
    reach within the bounds)."""


class RunError(DmechError, RuntimeError):
    """A run that started and failed: a simulation step that did not converge, a closed
    loop whose plant diverged."""


_KINDS = {"bad_input": BadInputError, "run": RunError}

T = TypeVar("T")


def call(fn: Callable[..., T], *args: Any) -> T:
    """``fn(*args)`` of the native module, its failures raised as the documented
    exceptions."""
    try:
        return fn(*args)
    except _native.NativeError as e:
        kind, message = e.args
        raise _KINDS.get(kind, DmechError)(message) from None
