"""The front-wheel-steered car with a DC drive motor: plan (``car plan``).

>>> plan = dmech.car.plan("parallel-park")     # doctest: +SKIP
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

#: The car's state: pose (m, m, rad), steering angle (rad), rear-wheel angle (rad), the
#: motor's charge (C), steering rate (rad/s), wheel rate (rad/s), motor current (A).
STATE_NAMES = ("x", "y", "theta", "phi", "psi", "q", "v_phi", "v_psi", "i")
#: The inputs: the steering torque (N m) and the drive voltage (V).
INPUT_NAMES = ("tau_s", "u_d")


@dataclasses.dataclass(eq=False)
class Plan(SolvedPlan):
    """A plan of the car (``car plan``'s trajectory.csv and summary.json)."""

    state_names: Tuple[str, ...] = STATE_NAMES
    input_names: Tuple[str, ...] = INPUT_NAMES
    pose_error_max: float = float("nan")


def plan(
    problem: Union[str, os.PathLike, Mapping[str, Any]] = "parallel-park",
    *,
    step: float = 0.02,
    integrator: str = "first-order",
    max_iter: int = 500,
    threads: Optional[int] = None,
    hessian: str = "sr1",
    verbose: bool = False,
    progress: Optional[Callable[[SolverProgress], Any]] = None,
) -> Plan:
    """Plan a rest-to-rest manoeuvre of the car.

    ``problem``: ``"parallel-park"``, ``"lane-change"``, a pose file's path, or its keys
    as a dict (``start``, ``end`` and optional ``waypoints`` as ``(x, y, heading)``,
    ``duration``, optional ``reverse`` and ``name``; docs/car.md). ``integrator``:
    ``"first-order"`` or ``"midpoint"``. Raises as :func:`dmech.wip.plan` does.
    """
    name, poses = problem_args(problem, "pose")
    d = call(
        _native.car_plan, name, poses, float(step), integrator, int(max_iter), threads,
        hessian, bool(verbose), progress_callback(progress),
    )
    result = Plan(
        **series(d["table"], STATE_NAMES, INPUT_NAMES),
        **solve_fields(d),
        pose_error_max=d["pose_error_max"],
    )
    return raise_unless_solved(d, result)
