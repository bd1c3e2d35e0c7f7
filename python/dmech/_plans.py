"""What every robot's plan shares: the problem as a name, a file or a dict, the solver's
keyword arguments, the progress callback, and the result's solve figures."""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any, Callable, Dict, Mapping, NamedTuple, Optional, Tuple, Union

import numpy as np

from ._tables import TimeSeries
from .errors import BadInputError, InfeasibleError, NotSolvedError


class SolverProgress(NamedTuple):
    """One iteration of the solver, as its iteration table prints it."""

    iteration: int
    #: the solve's number of stages (a mesh sequence solves once per mesh)
    stages: int
    #: the objective the solver minimises, scaled as the iteration table prints it
    objective: float
    primal_infeasibility: float
    dual_infeasibility: float
    barrier: float
    elapsed_s: float


@dataclasses.dataclass(eq=False)
class SolvedPlan(TimeSeries):
    """A plan: its trajectory and how the solve went (the figures of ``summary.json``)."""

    name: str = ""
    status: str = ""
    objective: float = float("nan")
    iterations: int = 0
    max_violation: float = float("nan")
    solve_time_s: float = float("nan")
    step: float = float("nan")
    integrator: str = ""
    summary: Dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def solved(self) -> bool:
        return self.status == "solved"


def problem_args(problem: Any, what: str) -> Tuple[Optional[str], Optional[str]]:
    """``(name_or_path, json)``: a problem's name or file path, or a dict as file JSON."""
    if isinstance(problem, Mapping):
        p = {k: (np.asarray(v, dtype=float).tolist() if isinstance(v, np.ndarray) else v)
             for k, v in problem.items()}
        return None, json.dumps(p)
    if isinstance(problem, (str, os.PathLike)):
        return os.fspath(problem), None
    raise BadInputError(f"problem must be a built-in's name, a {what} file's path or a dict")


def progress_callback(progress: Optional[Callable[[SolverProgress], Any]]):
    """The native callback for ``progress``: rows of the table as :class:`SolverProgress`."""
    if progress is None:
        return None
    return lambda *row: progress(SolverProgress(*row))


def raise_unless_solved(d: Dict[str, Any], result: Any) -> Any:
    """``result``, or the documented exception with it if the plan was not solved."""
    if d["message"] is not None:
        cls = InfeasibleError if d["status"] == "infeasible" else NotSolvedError
        raise cls(d["message"], result)
    return result


def solve_fields(d: Dict[str, Any]) -> Dict[str, Any]:
    """The fields every :class:`SolvedPlan` takes from a native plan."""
    return {
        "name": d["name"],
        "status": d["status"],
        "objective": d["objective"],
        "iterations": d["iterations"],
        "max_violation": d["max_violation"],
        "solve_time_s": d["solve_time_s"],
        "step": d["step"],
        "integrator": d["integrator"],
        "summary": json.loads(d["summary"]),
    }
