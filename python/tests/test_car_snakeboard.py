"""dmech.car and dmech.snakeboard against their command lines: the same plans to the bit,
the same refusals."""

import csv
import json

import numpy as np
import pytest

import dmech
from conftest import read_summary


def rows(path):
    with open(path, encoding="utf-8") as f:
        return np.array([[float(v) for v in r] for r in list(csv.reader(f))[1:]])


@pytest.mark.parametrize(
    "module, tool, problem, args",
    [
        (dmech.car, "car", "parallel-park", {}),
        (dmech.car, "car", "lane-change", {"integrator": "midpoint"}),
        (dmech.snakeboard, "snakeboard", "forward", {}),
    ],
)
def test_plans_are_the_command_lines_to_the_bit(module, tool, problem, args, cli, tmp_path):
    ours = module.plan(problem, **args)
    flags = [x for k, v in args.items() for x in (f"--{k}", v)]
    r = cli(tool, "plan", problem, *flags, "--quiet", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    s = read_summary(tmp_path)
    assert ours.solved
    assert (ours.objective, ours.iterations) == (s["objective"], s["iterations"])
    table = np.column_stack([ours.t, ours.states, ours.inputs])
    assert np.array_equal(table, rows(tmp_path / "trajectory.csv"))
    assert ours.summary["N"] == len(ours.t) - 1


def test_a_pose_dict_plans_like_the_pose_file(tmp_path):
    poses = {"name": "hop", "start": [0, 0, 0], "end": [1.0, 0.2, 0.0], "duration": 4.0}
    a = dmech.car.plan(poses)
    path = tmp_path / "hop.json"
    path.write_text(json.dumps(poses))
    b = dmech.car.plan(str(path))
    assert a.solved and np.array_equal(a.states, b.states)


def test_car_refusals_carry_the_command_lines_message(cli, tmp_path):
    path = tmp_path / "spin.json"
    path.write_text(json.dumps({"start": [0, 0, 0], "end": [0, 0, 1.0], "duration": 3.0}))
    r = cli("car", "plan", path, "--out", tmp_path / "o")
    assert r.returncode == 1
    with pytest.raises(dmech.BadInputError) as e:
        dmech.car.plan(str(path))
    assert r.stderr.strip().splitlines()[-1].endswith(str(e.value))
    with pytest.raises(dmech.BadInputError, match="variational"):
        dmech.car.plan("parallel-park", integrator="rk4")
    with pytest.raises(dmech.BadInputError, match="unknown start"):
        dmech.snakeboard.plan("forward", start="sideways")
