"""The wheeled inverted pendulum (WIP) with DC motors: plan, simulate, track, generate and
diagnose; its parameters.

>>> import dmech
>>> plan = dmech.wip.plan("eight")                       # doctest: +SKIP
>>> plan.objective, plan.iterations                       # doctest: +SKIP
(4877.158473..., 58)
>>> plan.states[:, plan.state_names.index("alpha")].max() # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any, Callable, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._tables import TimeSeries, series
from ._plans import SolvedPlan, SolverProgress, problem_args, progress_callback, raise_unless_solved, solve_fields
from .errors import BadInputError, call
from ._wip_params import Params, ParamsLike, params, params_json as _params_json

__all__ = [
    "STATE_NAMES",
    "INPUT_NAMES",
    "Params",
    "Plan",
    "SolverProgress",
    "Trajectory",
    "params",
    "plan",
    "simulate",
    "track",
    "Tracking",
    "MonteCarlo",
    "TRACKING_COLUMNS",
    "generate",
    "GeneratedLog",
    "diagnose",
    "Diagnosis",
    "Cause",
]

#: The reduced state of every trajectory, in order: pose (m, m, rad), tilt (rad), tilt
#: rate (rad/s), speed (m/s), heading rate (rad/s), motor currents (A).
STATE_NAMES = ("x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL")
#: The inputs: the two motor voltages (V).
INPUT_NAMES = ("uR", "uL")


@dataclasses.dataclass(eq=False)
class Trajectory(TimeSeries):
    """A trajectory of the WIP: times ``t`` (s), ``states`` (columns :data:`STATE_NAMES`)
    and ``inputs`` (the voltages applied from each node on, :data:`INPUT_NAMES`; the last
    row repeats the one before)."""

    state_names: Tuple[str, ...] = STATE_NAMES
    input_names: Tuple[str, ...] = INPUT_NAMES


def trajectory_csv(trajectory: TimeSeries) -> str:
    """A trajectory as ``trajectory.csv``'s text (17 significant digits: exact)."""
    header = ",".join(("t",) + STATE_NAMES + INPUT_NAMES)
    rows = np.column_stack([trajectory.t, trajectory.states, trajectory.inputs])
    lines = [header]
    lines += [repr(float(r[0])) + "".join(f",{v:.17e}" for v in r[1:]) for r in rows]
    return "\n".join(lines) + "\n"


def _trajectory(d: Dict[str, Any]) -> Dict[str, Any]:
    return series(d, STATE_NAMES, INPUT_NAMES)


@dataclasses.dataclass(eq=False)
class Plan(SolvedPlan):
    """A plan of :func:`plan`: its trajectory (as :class:`Trajectory`) and how the solve
    went (the figures of ``summary.json``)."""

    state_names: Tuple[str, ...] = STATE_NAMES
    input_names: Tuple[str, ...] = INPUT_NAMES
    duality_gap: float = float("nan")
    setup_time_s: float = float("nan")
    current: str = ""
    waypoints: np.ndarray = dataclasses.field(default_factory=lambda: np.empty((0, 2)))
    waypoint_stages: np.ndarray = dataclasses.field(default_factory=lambda: np.empty(0, int))

    def save(self, directory: Union[str, os.PathLike]) -> None:
        """Write ``trajectory.csv`` and ``summary.json`` into ``directory`` (created if
        missing), as ``wip plan`` writes them; ``wip track DIR`` reads the folder."""
        os.makedirs(directory, exist_ok=True)
        with open(os.path.join(directory, "trajectory.csv"), "w", encoding="utf-8") as f:
            f.write(trajectory_csv(self))
        with open(os.path.join(directory, "summary.json"), "w", encoding="utf-8") as f:
            json.dump(self.summary, f, indent=2)
            f.write("\n")


def plan(
    problem: Union[str, os.PathLike, Mapping[str, Any]] = "eight",
    *,
    step: float = 0.005,
    integrator: str = "first-order",
    current: str = "dynamic",
    params: Optional[ParamsLike] = None,
    u_max: float = 5.0,
    free_timing: bool = False,
    time_price: Optional[float] = None,
    max_iter: int = 500,
    max_stages: int = 100_000,
    threads: Optional[int] = None,
    hessian: str = "sr1",
    verbose: bool = False,
    progress: Optional[Callable[[SolverProgress], Any]] = None,
) -> Plan:
    """Plan the WIP's least-energy motion through waypoints (``wip plan``).

    ``problem`` is a benchmark's name (``"eight"``, ``"zigzag"``), a waypoint file's path,
    or the waypoints as a dict with the file's keys (``points`` an array of ``(x, y)``,
    ``duration``, ``start_heading``, ``end_heading``, optional ``accel`` and ``name``).
    ``integrator``: ``"first-order"`` (the paper's), ``"midpoint"``, ``"rk1"``, ``"rk2"``,
    ``"rk4"``; ``current``: ``"dynamic"`` or ``"algebraic"``. ``verbose`` prints the
    solver's iteration table on stderr; ``progress``, if given, is called after every
    iteration with a :class:`SolverProgress` (an exception it raises is raised when the
    solve returns). The solve runs without the GIL.

    Raises :class:`BadInputError` for a refused request (the command line's message),
    :class:`InfeasibleError` or :class:`NotSolvedError` (with the plan as ``.result``)
    when it is not solved.
    """
    name, waypoints = problem_args(problem, "waypoint")
    d = call(
        _native.wip_plan,
        name,
        waypoints,
        float(step),
        integrator,
        current,
        _params_json(params),
        float(u_max),
        int(max_iter),
        int(max_stages),
        threads,
        bool(free_timing),
        time_price,
        hessian,
        bool(verbose),
        progress_callback(progress),
    )
    result = Plan(
        **_trajectory(d["table"]),
        **solve_fields(d),
        duality_gap=d["duality_gap"],
        setup_time_s=d["setup_time_s"],
        current=d["current"],
        waypoints=np.asarray(d["waypoints"], dtype=float).reshape(-1, 2),
        waypoint_stages=np.asarray(d["waypoint_stages"], dtype=int),
    )
    return raise_unless_solved(d, result)


def _inputs_csv(inputs: Any, names: Sequence[str]) -> str:
    """``t`` and the named inputs as CSV text (17 significant digits: exact)."""
    cols = list(("t",) + tuple(names))
    if hasattr(inputs, "to_dict") and hasattr(inputs, "columns"):  # a DataFrame
        missing = [c for c in cols if c not in inputs.columns]
        if missing:
            raise BadInputError(f"inputs: missing column '{missing[0]}' (expected {','.join(cols)})")
        data = np.column_stack([np.asarray(inputs[c], dtype=float) for c in cols])
    elif isinstance(inputs, Mapping):
        missing = [c for c in cols if c not in inputs]
        if missing:
            raise BadInputError(f"inputs: missing column '{missing[0]}' (expected {','.join(cols)})")
        data = np.column_stack([np.asarray(inputs[c], dtype=float) for c in cols])
    else:
        data = np.asarray(inputs, dtype=float)
        if data.ndim != 2 or data.shape[1] != len(cols):
            raise BadInputError(
                f"inputs: expected an array of shape (n, {len(cols)}) with columns {','.join(cols)}, got shape {data.shape}"
            )
    lines = [",".join(cols)]
    lines += [",".join(repr(float(v)) for v in row) for row in data]
    return "\n".join(lines) + "\n"


def simulate(
    x0: Sequence[float],
    inputs: Any,
    *,
    integrator: str = "first-order",
    step: float = 0.005,
    params: Optional[ParamsLike] = None,
    max_steps: int = 2_000_000,
    max_voltage: float = 24.0,
) -> Trajectory:
    """Simulate the WIP open loop from the reduced state ``x0`` (:data:`STATE_NAMES`) with
    the voltages ``inputs`` held from each row's time (``wip simulate``).

    ``inputs``: an array of rows ``(t, uR, uL)``, a dict of columns, or a DataFrame with
    columns ``t, uR, uL``; the first row at ``t = 0``, every row on the step grid, the last
    row's ``t`` the end of the run (in messages, line 1 is the header: row ``i`` is line
    ``i + 2``). The run is checked as the command line checks it and runs without the GIL.
    """
    d = call(
        _native.wip_simulate,
        [float(v) for v in np.asarray(x0, dtype=float).ravel()],
        _inputs_csv(inputs, INPUT_NAMES),
        float(step),
        integrator,
        _params_json(params),
        int(max_steps),
        float(max_voltage),
    )
    return Trajectory(**_trajectory(d["table"]))


from ._wip_diagnose import Cause, Diagnosis, GeneratedLog, diagnose, generate  # noqa: E402
from ._wip_track import TRACKING_COLUMNS, MonteCarlo, Tracking, track  # noqa: E402
