"""The WIP's closed loop along a plan (``wip track``): :func:`track`, :class:`Tracking`,
:class:`MonteCarlo`."""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any, Callable, Dict, Optional, Tuple, Union

import numpy as np

from . import _native
from ._tables import Result, table
from ._wip_params import ParamsLike, params_json
from .errors import BadInputError, call

#: The columns of ``tracking.csv``: time, the true pose and tilt, the plan's, the
#: observer's pose, and the feedforward, feedback and applied voltages.
TRACKING_COLUMNS = (
    "t", "x", "y", "theta", "alpha", "x_ref", "y_ref", "theta_ref", "alpha_ref",
    "x_est", "y_est", "theta_est", "uR_ff", "uL_ff", "uR_fb", "uL_fb", "uR", "uL",
)


@dataclasses.dataclass(eq=False)
class Tracking(Result):
    """A closed-loop run along a plan: one row per 5-ms controller sample.

    ``columns`` holds the columns of ``tracking.csv`` (:data:`TRACKING_COLUMNS`) as arrays
    (full precision); ``figures`` is ``tracking.json`` (position and heading errors, tilt,
    feedback voltage, the MPC's QP times, the outcome)."""

    columns: Dict[str, np.ndarray]
    figures: Dict[str, Any]

    @property
    def t(self) -> np.ndarray:
        return self.columns["t"]

    @property
    def controller(self) -> str:
        return self.figures["controller"]

    @property
    def fell(self) -> bool:
        """Whether the robot fell (|α| > 45°); the run ends there."""
        return bool(self.figures["fell"])

    @property
    def fell_at(self) -> Optional[float]:
        return self.figures["fell_at_s"]

    @property
    def position_error_max_m(self) -> float:
        return self.figures["position_error_max_m"]

    @property
    def position_error_rms_m(self) -> float:
        return self.figures["position_error_rms_m"]

    def position_error(self) -> np.ndarray:
        """The distance between the true and the planned position at every sample (m)."""
        c = self.columns
        return np.hypot(c["x"] - c["x_ref"], c["y"] - c["y_ref"])

    def to_pandas(self):
        """``tracking.csv`` as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame({n: self.columns[n] for n in TRACKING_COLUMNS})


@dataclasses.dataclass(eq=False)
class MonteCarlo(Result):
    """Closed-loop runs of seeds ``1..n``, each plant with its own parameter error.

    ``runs[i]`` is seed ``seeds[i]``'s ``tracking.json`` figures; a run whose plant's
    simulation diverged (a numerical failure, not a fall) has ``diverged_at`` set and is
    left out of the quantiles, as ``wip track --monte-carlo`` leaves it out."""

    controller: str
    param_error: float
    seeds: np.ndarray
    runs: Tuple[Dict[str, Any], ...]
    diverged_at: Tuple[Optional[float], ...]

    @property
    def fallen_seeds(self) -> list:
        return [int(s) for s, r in zip(self.seeds, self.runs) if r["fell"]]

    @property
    def falls(self) -> int:
        return len(self.fallen_seeds)

    def figure(self, name: str) -> np.ndarray:
        """One figure (a key of ``tracking.json``) over the runs that did not diverge."""
        return np.array([r[name] for r, d in zip(self.runs, self.diverged_at) if d is None], dtype=float)

    def quantile(self, name: str, q: float) -> float:
        """The ``q``-quantile of a figure (linear between order statistics, as the command
        line's ``montecarlo.json``)."""
        v = self.figure(name)
        return float(np.quantile(v, q)) if v.size else float("nan")


def _plan_csv(plan: Any) -> Tuple[str, str]:
    """``(text, name)`` of the plan to track: a :class:`dmech.wip.Plan` or
    :class:`dmech.wip.Trajectory`, or a ``trajectory.csv`` path or its directory."""
    from .wip import trajectory_csv  # the trajectory's columns are wip's

    if isinstance(plan, (str, os.PathLike)):
        path = os.fspath(plan)
        if os.path.isdir(path):
            path = os.path.join(path, "trajectory.csv")
        try:
            with open(path, encoding="utf-8") as f:
                return f.read(), path
        except OSError as e:
            raise BadInputError(f"plan {path}: {e.strerror}") from None
    if all(hasattr(plan, a) for a in ("t", "states", "inputs")):
        return trajectory_csv(plan), "plan"
    raise BadInputError("plan must be a Plan, a Trajectory, or a trajectory.csv path or directory")


def track(
    plan: Any,
    *,
    controller: str = "lq",
    seed: int = 1,
    ideal: bool = False,
    params: Optional[ParamsLike] = None,
    plant_seed: Optional[int] = None,
    param_error: float = 0.1,
    mean_delay: Optional[float] = None,
    monte_carlo: Optional[int] = None,
    threads: int = 2,
    progress: Optional[Callable[[float], Any]] = None,
) -> Union[Tracking, MonteCarlo]:
    """Track a plan in closed loop (``wip track``): the plan's voltages as feedforward, the
    feedback (``controller``: ``"lq"``, the paper's LQ, ``"mpc"``, a QP per sample, or
    ``"nmpc"``, the nonlinear MPC on the plan's transcription) on the observer's errors,
    saturated at ±5 V, applied to the nonlinear model with the sensors' rates, delays and
    noise (drawn from ``seed``).

    ``plan``: a :class:`~dmech.wip.Plan` or :class:`~dmech.wip.Trajectory`, or a
    ``trajectory.csv`` path or its directory. ``params``: the nominal robot (the design's);
    ``plant_seed``: track on the plant of Monte Carlo seed N instead (every mass, inertia and
    motor parameter off by up to ``param_error``); ``ideal``: no noise, delay or loss;
    ``mean_delay``: the external pose's mean delay (s). With ``monte_carlo = n``, seeds
    ``1..n`` on ``threads`` threads, returned as a :class:`MonteCarlo`; else one run as a
    :class:`Tracking`. A fall is a result (``.fell``), not an exception. ``progress`` gets the
    fraction done every 5 % of a single run. Runs without the GIL.

    Raises :class:`BadInputError` for a refused request or plan (the command line's
    message) and :class:`RunError` if the plant's simulation diverges.
    """
    text, _ = _plan_csv(plan)
    d = call(
        _native.wip_track,
        text,
        controller,
        int(seed),
        bool(ideal),
        params_json(params),
        None if plant_seed is None else int(plant_seed),
        float(param_error),
        None if mean_delay is None else float(mean_delay),
        None if monte_carlo is None else int(monte_carlo),
        int(threads),
        progress,
    )
    if monte_carlo is not None:
        rows = json.loads(d["runs"])
        return MonteCarlo(
            controller=d["controller"],
            param_error=float(param_error),
            seeds=np.array([r["seed"] for r in rows], dtype=int),
            runs=tuple(r["figures"] for r in rows),
            diverged_at=tuple(r["diverged_at"] for r in rows),
        )
    return Tracking(columns=table(d["table"]), figures=json.loads(d["figures"]))
