"""dmech: discrete mechanics and structure-preserving optimal control of nonholonomic
robots, from Python.

One module per robot: :mod:`dmech.wip` (the wheeled inverted pendulum),
:mod:`dmech.car`, :mod:`dmech.snakeboard`. Every function
takes keyword arguments and numpy arrays, returns result objects with named fields, and
raises the exceptions of :mod:`dmech.errors`. Long runs release the GIL.
"""

from . import car, errors, snakeboard, wip
from ._native import __version__
from .errors import BadInputError, DmechError, InfeasibleError, NotSolvedError, RunError

__all__ = [
    "__version__",
    "errors",
    "wip",
    "car",
    "snakeboard",
    "DmechError",
    "BadInputError",
    "NotSolvedError",
    "InfeasibleError",
    "RunError",
]
