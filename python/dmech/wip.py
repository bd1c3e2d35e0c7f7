"""The wheeled inverted pendulum (WIP) with DC motors: plan, simulate, parameters.

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
]

#: The reduced state of every trajectory, in order: pose (m, m, rad), tilt (rad), tilt
#: rate (rad/s), speed (m/s), heading rate (rad/s), motor currents (A).
STATE_NAMES = ("x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL")
#: The inputs: the two motor voltages (V).
INPUT_NAMES = ("uR", "uL")


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


def _params_json(p: Optional[Union[Params, Mapping[str, float], str, os.PathLike]]) -> Optional[str]:
    if p is None:
        return None
    if isinstance(p, Params):
        return p.to_json()
    if isinstance(p, Mapping):
        return json.dumps(dict(p))
    return Params.load(p).to_json()


@dataclasses.dataclass(eq=False)
class Trajectory(TimeSeries):
    """A trajectory of the WIP: times ``t`` (s), ``states`` (columns :data:`STATE_NAMES`)
    and ``inputs`` (the voltages applied from each node on, :data:`INPUT_NAMES`; the last
    row repeats the one before)."""

    state_names: Tuple[str, ...] = STATE_NAMES
    input_names: Tuple[str, ...] = INPUT_NAMES


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
        header = ",".join(("t",) + STATE_NAMES + INPUT_NAMES)
        rows = np.column_stack([self.t, self.states, self.inputs])
        with open(os.path.join(directory, "trajectory.csv"), "w", encoding="utf-8") as f:
            f.write(header + "\n")
            for r in rows:
                f.write(repr(float(r[0])) + "".join(f",{v:.17e}" for v in r[1:]) + "\n")
        with open(os.path.join(directory, "summary.json"), "w", encoding="utf-8") as f:
            json.dump(self.summary, f, indent=2)
            f.write("\n")


def plan(
    problem: Union[str, os.PathLike, Mapping[str, Any]] = "eight",
    *,
    step: float = 0.005,
    integrator: str = "first-order",
    current: str = "dynamic",
    params: Optional[Union[Params, Mapping[str, float], str, os.PathLike]] = None,
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
    params: Optional[Union[Params, Mapping[str, float], str, os.PathLike]] = None,
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
