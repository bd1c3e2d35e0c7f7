"""dmech.wip against the command line: the same numbers to the bit, the same refusals with
the same messages, and the package's own behaviour (pickling, parameters, threads)."""

import csv
import json
import pickle
import threading

import numpy as np
import pytest

import dmech
from conftest import read_summary


@pytest.fixture(scope="module")
def eight():
    return dmech.wip.plan("eight")


def test_the_eight_is_the_command_lines_to_the_bit(eight, cli, tmp_path):
    r = cli("wip", "plan", "eight", "--quiet", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    s = read_summary(tmp_path)
    assert eight.status == "solved" and eight.solved
    assert eight.objective == s["objective"]
    assert eight.iterations == s["iterations"]
    assert eight.max_violation == s["max_violation"]
    # The whole trajectory, from trajectory.csv's 17 significant digits.
    with open(tmp_path / "trajectory.csv", encoding="utf-8") as f:
        rows = np.array([[float(v) for v in row] for row in list(csv.reader(f))[1:]])
    ours = np.column_stack([eight.t, eight.states, eight.inputs])
    assert np.array_equal(ours, rows)


def test_a_plan_has_named_columns_and_its_summary(eight):
    n = len(eight.t)
    assert eight.states.shape == (n, 9) and eight.inputs.shape == (n, 2)
    assert eight.column("alpha") is not None
    assert np.array_equal(eight.column("uR"), eight.inputs[:, 0])
    assert eight.summary["N"] == n - 1
    assert eight.waypoints.shape == (9, 2)
    # The plan passes through its waypoints at their stages.
    at = eight.states[eight.waypoint_stages][:, :2]
    assert np.max(np.hypot(*(at - eight.waypoints).T)) < 1e-6


def test_a_plan_pickles(eight):
    back = pickle.loads(pickle.dumps(eight))
    assert back == eight
    assert back.objective == eight.objective


def test_waypoints_as_a_dict_plan_like_the_file(tmp_path):
    w = {
        "name": "corner",
        "points": np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]),
        "duration": 12.0,
        "start_heading": 0.0,
        "end_heading": 1.5708,
    }
    a = dmech.wip.plan(w, step=0.02)
    path = tmp_path / "corner.json"
    path.write_text(json.dumps({**w, "points": w["points"].tolist()}))
    b = dmech.wip.plan(str(path), step=0.02)
    assert a.solved and b.solved
    assert a.objective == b.objective and a.iterations == b.iterations
    assert np.array_equal(a.states, b.states) and np.array_equal(a.inputs, b.inputs)


def test_a_bad_waypoint_set_raises_the_command_lines_message(cli, tmp_path):
    path = tmp_path / "bad.json"
    path.write_text(
        json.dumps({"points": [[0, 0], [0, 0], [1, 1]], "duration": 10.0,
                    "start_heading": 0.0, "end_heading": 0.0})
    )
    r = cli("wip", "plan", path, "--out", tmp_path / "out")
    assert r.returncode == 1
    line = r.stderr.strip().splitlines()[-1]
    with pytest.raises(dmech.BadInputError) as e:
        dmech.wip.plan(str(path))
    assert line == f"wip: error: {e.value}"
    assert isinstance(e.value, ValueError)
    with pytest.raises(dmech.BadInputError, match=r"points\[1\] repeats points\[0\]"):
        dmech.wip.plan(json.loads(path.read_text()))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"step": 0.5}, r"the step must be in \(0, 0.1\] s, got 0.5"),
        ({"u_max": 6.0}, r"6(\.0)? V is outside \(0, 5\] V"),
        ({"integrator": "rk5"}, r"rk5"),
        ({"integrator": "rk1", "free_timing": True}, r"--free-timing needs --integrator first-order"),
        ({"params": {"m_b": -1.0}}, r"m_b"),
        ({"params": {"colour": 1.0}}, r"colour"),
    ],
)
def test_refused_requests_raise_bad_input(kwargs, message):
    with pytest.raises(dmech.BadInputError, match=message):
        dmech.wip.plan("eight", **kwargs)


def test_a_plan_not_solved_carries_its_result():
    with pytest.raises(dmech.NotSolvedError) as e:
        dmech.wip.plan("zigzag", max_iter=3, step=0.02)
    assert "not solved within" in str(e.value)
    assert e.value.result.status == "max_iterations"
    assert len(e.value.result.t) == e.value.result.summary["N"] + 1
    back = pickle.loads(pickle.dumps(e.value))
    assert back.result == e.value.result


def test_parameters_round_trip_the_file_format(cli, tmp_path):
    p = dmech.wip.params()
    r = cli("wip", "params")
    assert r.returncode == 0
    assert p == dmech.wip.Params.from_json(r.stdout)
    q = p.replace(m_b=p.m_b * 1.1)
    q.save(tmp_path / "p.json")
    assert dmech.wip.Params.load(tmp_path / "p.json") == q
    assert pickle.loads(pickle.dumps(q)) == q
    with pytest.raises(dmech.BadInputError):
        p.replace(R_m=0.0)


def test_simulate_is_the_command_lines_to_the_bit(cli, tmp_path):
    t = np.arange(0, 1.0 + 1e-12, 0.005)
    u = np.column_stack([t, 0.5 * np.sin(3 * t), 0.4 * np.cos(2 * t)])
    x0 = [0, 0, 0, 0.02, 0, 0, 0, 0, 0]
    ours = dmech.wip.simulate(x0, u, integrator="midpoint", step=0.005)
    path = tmp_path / "u.csv"
    path.write_text("t,uR,uL\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in u))
    r = cli("wip", "simulate", "--x0", ",".join(map(str, x0)), "--inputs", path,
            "--integrator", "midpoint", "--out", tmp_path / "sim")
    assert r.returncode == 0, r.stderr
    with open(tmp_path / "sim" / "trajectory.csv", encoding="utf-8") as f:
        rows = np.array([[float(v) for v in row] for row in list(csv.reader(f))[1:]])
    assert np.array_equal(np.column_stack([ours.t, ours.states, ours.inputs]), rows)
    # A DataFrame with the same columns gives the same run.
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"t": u[:, 0], "uR": u[:, 1], "uL": u[:, 2]})
    assert dmech.wip.simulate(x0, frame, integrator="midpoint") == ours


def test_simulate_refuses_inputs_off_the_grid():
    u = np.array([[0.0, 0.0, 0.0], [0.0123, 0.1, 0.1], [0.1, 0.0, 0.0]])
    with pytest.raises(dmech.BadInputError, match="not a whole number of steps"):
        dmech.wip.simulate([0] * 9, u)


def test_the_solve_releases_the_gil():
    """While a plan solves in another thread, this thread runs Python code: it could not
    if the solve held the GIL."""
    done = threading.Event()
    spins = 0

    def solve():
        dmech.wip.plan("zigzag", step=0.01)
        done.set()

    worker = threading.Thread(target=solve)
    worker.start()
    while not done.is_set():
        spins += 1
    worker.join()
    # The solve takes tens of milliseconds at least; a thread held off by the GIL would
    # run only at the solve's start and end (a handful of iterations of this loop).
    assert spins > 10_000


def test_progress_reports_every_iteration_of_every_mesh():
    seen = []
    p = dmech.wip.plan("zigzag", step=0.01, progress=seen.append)
    assert all(isinstance(r, dmech.wip.SolverProgress) for r in seen)
    # Mesh sequencing solves the coarse meshes first, the plan's own last.
    assert seen[-1].stages == p.summary["N"]
    assert len(seen) >= p.iterations
    assert seen[-1].primal_infeasibility < 1e-8


def test_an_exception_in_the_callback_is_raised_after_the_solve():
    def fail(_):
        raise KeyError("stop")

    with pytest.raises(KeyError, match="stop"):
        dmech.wip.plan("zigzag", step=0.02, progress=fail)
