"""Type stubs of the extension module ``dmech._native`` (the Rust side of the package).
Users call the Python modules (:mod:`dmech.wip`, :mod:`dmech.car`,
:mod:`dmech.snakeboard`), which wrap these."""

from typing import Any, Callable, Dict, Optional

__version__: str

class NativeError(Exception):
    """``args == (kind, message)``; the package raises ``dmech.errors`` instead."""

Table = Dict[str, Any]  # {"columns": list[str], "rows": int, "data": bytes}
Progress = Optional[Callable[..., Any]]

def wip_plan(
    problem: Optional[str],
    waypoints: Optional[str],
    step: float,
    integrator: str,
    current: str,
    params: Optional[str],
    u_max: float,
    max_iter: int,
    max_stages: int,
    threads: Optional[int],
    free_timing: bool,
    time_price: Optional[float],
    hessian: str,
    verbose: bool,
    progress: Progress,
) -> Dict[str, Any]: ...
def wip_simulate(
    x0: list,
    inputs_csv: str,
    step: float,
    integrator: str,
    params: Optional[str],
    max_steps: int,
    max_voltage: float,
) -> Dict[str, Any]: ...
def wip_default_params() -> str: ...
def wip_check_params(json: str) -> str: ...
def car_plan(
    problem: Optional[str],
    poses: Optional[str],
    step: float,
    integrator: str,
    max_iter: int,
    threads: Optional[int],
    hessian: str,
    verbose: bool,
    progress: Progress,
) -> Dict[str, Any]: ...
def snakeboard_plan(
    problem: Optional[str],
    poses: Optional[str],
    step: float,
    integrator: str,
    start: str,
    max_iter: int,
    threads: Optional[int],
    hessian: str,
    verbose: bool,
    progress: Progress,
) -> Dict[str, Any]: ...
def wip_track(
    plan_csv: str,
    controller: str,
    seed: int,
    ideal: bool,
    params: Optional[str],
    plant_seed: Optional[int],
    param_error: float,
    mean_delay: Optional[float],
    monte_carlo: Optional[int],
    threads: int,
    progress: Progress,
) -> Dict[str, Any]: ...
def wip_generate(effect: str, seed: int, duration: float, params: Optional[str]) -> Dict[str, Any]: ...
def wip_diagnose(
    log_csv: str,
    source: str,
    params: Optional[str],
    window: float,
    threads: Optional[int],
    calibrate: Optional[str],
    exclude: list,
    max_effects: int,
    progress: Progress,
) -> Dict[str, Any]: ...
