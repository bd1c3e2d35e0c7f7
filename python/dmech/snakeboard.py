"""The snakeboard, which moves by the momentum its rotor and axles build up: plan
(``snakeboard plan``).

>>> plan = dmech.snakeboard.plan("sideways")   # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any, Callable, Mapping, Optional, Tuple, Union

from . import _native
from ._plans import SolvedPlan, SolverProgress, problem_args, progress_callback, raise_unless_solved, solve_fields
from ._tables import series
from .errors import call

__all__ = ["STATE_NAMES", "INPUT_NAMES", "Plan", "plan"]

#: The snakeboard's state: pose (m, m, rad), rotor and axle angles (rad), their rates
#: (rad/s), the forward speed along the free direction ``p`` (m/s) and the momentum ``J``.
STATE_NAMES = ("x", "y", "theta", "psi", "phi", "v_psi", "v_phi", "p", "J")
#: The inputs: the rotor and axle torques (N m).
INPUT_NAMES = ("tau_psi", "tau_phi")


@dataclasses.dataclass(eq=False)
class Plan(SolvedPlan):
    """A plan of the snakeboard (``snakeboard plan``'s trajectory.csv and summary.json)."""

    state_names: Tuple[str, ...] = STATE_NAMES
    input_names: Tuple[str, ...] = INPUT_NAMES
    end_error: float = float("nan")


def plan(
    problem: Union[str, os.PathLike, Mapping[str, Any]] = "forward",
    *,
    step: float = 0.02,
    integrator: str = "midpoint",
    start: str = "excited",
    max_iter: int = 1000,
    threads: Optional[int] = None,
    hessian: str = "exact",
    verbose: bool = False,
    progress: Optional[Callable[[SolverProgress], Any]] = None,
) -> Plan:
    """Plan the snakeboard from rest to rest.

    ``problem``: ``"forward"``, ``"sideways"``, ``"turn"``, a pose file's path or its keys
    as a dict (docs/snakeboard.md). ``start``: ``"excited"`` (the default),
    ``"kinematic"``, ``"kinematic-excited"`` or ``"zero"``. Raises as
    :func:`dmech.wip.plan` does.
    """
    name, poses = problem_args(problem, "pose")
    d = call(
        _native.snakeboard_plan, name, poses, float(step), integrator, start, int(max_iter),
        threads, hessian, bool(verbose), progress_callback(progress),
    )
    result = Plan(
        **series(d["table"], STATE_NAMES, INPUT_NAMES),
        **solve_fields(d),
        end_error=d["end_error"],
    )
    return raise_unless_solved(d, result)
