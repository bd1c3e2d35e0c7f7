"""The WIP's diagnosis from a measured log (``wip generate``, ``wip diagnose``):
:func:`generate`, :func:`diagnose`, :class:`GeneratedLog`, :class:`Diagnosis`."""

from __future__ import annotations

import dataclasses
import io
import json
import math
import os
from typing import Any, Callable, Dict, Iterable, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._tables import Result
from ._wip_params import Params, ParamsLike, params_json
from .errors import BadInputError, call


def _csv_columns(text: str) -> Dict[str, np.ndarray]:
    """A CSV text's columns as float arrays (empty fields: NaN)."""
    lines = text.splitlines()
    header = lines[0].split(",")
    rows = [[float(v) if v else math.nan for v in line.split(",")] for line in lines[1:] if line]
    data = np.array(rows, dtype=float).reshape(len(rows), len(header))
    return {h: data[:, j].copy() for j, h in enumerate(header)}


def _columns_csv(columns: Mapping[str, Any]) -> str:
    """Columns (a dict of arrays or a DataFrame) as CSV text: exact values, NaN as an
    empty field (a missing reading)."""
    names = list(columns.keys()) if isinstance(columns, Mapping) else list(columns.columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    fmt = lambda v: "" if math.isnan(v) else repr(float(v))  # noqa: E731
    lines = [",".join(names)]
    lines += [",".join(fmt(v) for v in row) for row in data]
    return "\n".join(lines) + "\n"


@dataclasses.dataclass(eq=False)
class GeneratedLog(Result):
    """A synthetic measured log (``wip generate``): ``csv`` is ``log.csv``'s text,
    ``columns`` its columns (missing readings NaN), ``truth`` the hidden effects and their
    parameters (``truth.json``)."""

    csv: str
    truth: Dict[str, Any]
    columns: Dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    def to_pandas(self):
        """The log as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.columns)

    def save(self, directory: Union[str, os.PathLike]) -> None:
        """Write ``log.csv`` and ``truth.json`` into ``directory`` (created if missing)."""
        os.makedirs(directory, exist_ok=True)
        with open(os.path.join(directory, "log.csv"), "w", encoding="utf-8") as f:
            f.write(self.csv)
        with open(os.path.join(directory, "truth.json"), "w", encoding="utf-8") as f:
            json.dump(self.truth, f, indent=2)
            f.write("\n")


def generate(
    effect: Union[str, Sequence[str]] = "none",
    *,
    seed: int = 1,
    duration: float = 30.0,
    params: Optional[ParamsLike] = None,
) -> GeneratedLog:
    """A synthetic measured log: a closed-loop run of the robot with hidden ``effect``
    (a catalogue name, two joined by ``+`` or given as a list, or ``"none"``), magnitudes
    drawn from ``seed``, sensor noise as the command line's (``wip generate``). The same
    seed gives the same log as the command line, to the byte."""
    spec = effect if isinstance(effect, str) else "+".join(effect) or "none"
    d = call(_native.wip_generate, spec, int(seed), float(duration), params_json(params))
    return GeneratedLog(csv=d["log_csv"], truth=json.loads(d["truth"]), columns=_csv_columns(d["log_csv"]))


@dataclasses.dataclass(eq=False)
class Cause(Result):
    """A named effect: its parameters with their standard deviations."""

    effect: str
    parameters: Dict[str, float]
    uncertainty: Dict[str, float]


@dataclasses.dataclass(eq=False)
class Diagnosis(Result):
    """What ``wip diagnose`` finds: ``cause`` (the verdict: an effect's name, effects joined
    by ``+``, ``"none"`` or ``"unexplained"``), the named ``causes`` with their parameters
    and σ, the prediction error before and after (1 = the noise floor), the residuals per
    channel (``residuals.csv``'s columns), the refitted parameters, ``report_md`` and the
    whole ``diagnosis.json`` as ``json``."""

    cause: str
    causes: Tuple[Cause, ...]
    error_before: float
    error_after: float
    gain: float
    residuals: Dict[str, np.ndarray]
    params_refit: Params
    left_out: Tuple[str, ...]
    report_md: str
    json: Dict[str, Any]
    warnings: Tuple[str, ...] = ()

    @property
    def parameters(self) -> Dict[str, float]:
        """Every named effect's parameters in one dict (``diagnosis.json``'s)."""
        return dict(self.json.get("parameters", {}))

    @property
    def uncertainty(self) -> Dict[str, float]:
        return dict(self.json.get("uncertainty", {}))

    def residuals_to_pandas(self):
        import pandas as pd

        return pd.DataFrame(self.residuals)


def _log_text(log: Any) -> Tuple[str, str]:
    """``(csv, source)`` of a log: a path, a :class:`GeneratedLog`, a dict of arrays or a
    DataFrame (columns ``t``, the inputs ``uR, uL`` and any readings)."""
    if isinstance(log, GeneratedLog):
        return log.csv, "log"
    if isinstance(log, (str, os.PathLike)):
        path = os.fspath(log)
        try:
            with open(path, encoding="utf-8") as f:
                return f.read(), path
        except OSError as e:
            raise BadInputError(f"{path}: {e.strerror}") from None
    if isinstance(log, Mapping) or (hasattr(log, "columns") and hasattr(log, "__getitem__")):
        if "t" not in (log.keys() if isinstance(log, Mapping) else log.columns):
            raise BadInputError("log: missing column 't'")
        return _columns_csv(log), "log"
    raise BadInputError("log must be a path, a GeneratedLog, a dict of arrays or a DataFrame")


def _causes(j: Dict[str, Any]) -> Tuple[Cause, ...]:
    """The named effects with their parameters: a parameter belongs to the candidate whose
    parameters list it (``diagnosis.json``'s candidates)."""
    params, std = j.get("parameters", {}), j.get("uncertainty", {})
    out = []
    for name in j.get("effects", []):
        keys = next((c["parameters"].keys() for c in j.get("candidates", []) if c["effect"] == name), ())
        out.append(Cause(name, {k: params[k] for k in keys if k in params}, {k: std[k] for k in keys if k in std}))
    if not out and j.get("effects"):
        out = [Cause(n, {}, {}) for n in j["effects"]]
    return tuple(out)


def diagnose(
    log: Any,
    *,
    params: Optional[ParamsLike] = None,
    calibrate: Union[bool, Iterable[str]] = False,
    max_effects: int = 2,
    window: float = 0.5,
    threads: Optional[int] = None,
    exclude: Iterable[str] = (),
    progress: Optional[Callable[[str], Any]] = None,
) -> Diagnosis:
    """Compare the model with a measured log and name the unmodelled effect
    (``wip diagnose``).

    ``log``: a ``log.csv`` path, a :class:`GeneratedLog`, a dict of arrays or a pandas
    DataFrame with columns ``t``, ``uR``, ``uL`` and the readings (docs/formats.md; NaN or
    an empty field is a missing reading). ``calibrate``: ``True`` for the command line's
    default keys, or the parameter-file keys to calibrate first; ``exclude``: catalogue
    effects left out. ``progress`` gets the command line's progress lines. Runs without the
    GIL. Raises :class:`BadInputError` for a malformed log (the line and column named)."""
    text, source = _log_text(log)
    if calibrate is True:
        cal: Optional[str] = "default"
    elif calibrate is False or calibrate is None:
        cal = None
    else:
        cal = ",".join(calibrate)
    d = call(
        _native.wip_diagnose,
        text,
        source,
        params_json(params),
        float(window),
        threads,
        cal,
        list(exclude),
        int(max_effects),
        progress,
    )
    j = json.loads(d["diagnosis"])
    return Diagnosis(
        cause=j["cause"],
        causes=_causes(j),
        error_before=j["error_before"],
        error_after=j["error_after"],
        gain=j["gain"],
        residuals=_csv_columns(d["residuals_csv"]),
        params_refit=Params.from_json(d["params_refit"]),
        left_out=tuple(d["left_out"]),
        report_md=d["report_md"],
        json=j,
        warnings=tuple(d["warnings"]),
    )
