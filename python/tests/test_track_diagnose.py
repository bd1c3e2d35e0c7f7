"""dmech.wip.track, generate and diagnose against the command line: the same run, the same
log to the byte, the same verdict with the same parameters."""

import csv
import json

import numpy as np
import pytest

import dmech


@pytest.fixture(scope="module")
def eight_dir(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("eight")
    r = cli("wip", "plan", "eight", "--quiet", "--out", d)
    assert r.returncode == 0, r.stderr
    return d


def test_track_is_the_command_lines(eight_dir, cli, tmp_path):
    r = cli("wip", "track", eight_dir, "--seed", "2", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    run = dmech.wip.track(eight_dir, seed=2)
    with open(tmp_path / "tracking.json", encoding="utf-8") as f:
        assert run.figures == json.load(f)
    assert run.controller == "lq" and not run.fell
    # tracking.csv prints 10 significant digits: the package's full-precision columns
    # agree to half a unit of the 10th.
    with open(tmp_path / "tracking.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == run.t.size
    for name in dmech.wip.TRACKING_COLUMNS:
        printed = np.array([float(row[name]) for row in rows])
        np.testing.assert_allclose(run.columns[name], printed, rtol=5e-10, atol=0)
    assert run.position_error().max() == pytest.approx(run.position_error_max_m, rel=1e-12)


def test_a_plan_object_tracks_as_its_folder(eight_dir):
    plan = dmech.wip.plan("eight")
    assert dmech.wip.track(plan, ideal=True) == dmech.wip.track(eight_dir, ideal=True)


def test_monte_carlo_is_the_command_lines(eight_dir, cli, tmp_path):
    r = cli("wip", "track", eight_dir, "--monte-carlo", "4", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    mc = dmech.wip.track(eight_dir, monte_carlo=4)
    with open(tmp_path / "montecarlo.json", encoding="utf-8") as f:
        j = json.load(f)
    assert list(mc.seeds) == [1, 2, 3, 4]
    assert mc.falls == j["falls"] and mc.fallen_seeds == j["fallen_seeds"]
    assert mc.quantile("position_error_max_m", 0.5) == pytest.approx(
        j["position_error_max_m"]["median"], rel=1e-12)
    assert mc.quantile("position_error_max_m", 0.95) == pytest.approx(
        j["position_error_max_m"]["p95"], rel=1e-12)


def test_track_refuses_as_documented(eight_dir):
    with pytest.raises(dmech.BadInputError, match="unknown controller 'pid'"):
        dmech.wip.track(eight_dir, controller="pid")
    with pytest.raises(dmech.BadInputError, match=r"param_error must be in \(0, 1\)"):
        dmech.wip.track(eight_dir, param_error=1.5)
    with pytest.raises(dmech.BadInputError):
        dmech.wip.track(42)


@pytest.fixture(scope="module")
def delay_log(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("log")
    r = cli("wip", "generate", "--effect", "input_delay", "--seed", "2", "--duration", "10",
            "--out", d)
    assert r.returncode == 0, r.stderr
    return d


def test_generate_is_the_command_lines_to_the_byte(delay_log):
    g = dmech.wip.generate("input_delay", seed=2, duration=10)
    with open(delay_log / "log.csv", encoding="utf-8") as f:
        assert g.csv == f.read()
    with open(delay_log / "truth.json", encoding="utf-8") as f:
        assert g.truth == json.load(f)


def test_diagnose_names_the_command_lines_cause_with_its_parameters(delay_log, cli, tmp_path):
    r = cli("wip", "diagnose", delay_log / "log.csv", "--threads", "2", "--quiet", "--out",
            tmp_path)
    assert r.returncode == 0, r.stderr
    with open(tmp_path / "diagnosis.json", encoding="utf-8") as f:
        j = json.load(f)
    lines = []
    d = dmech.wip.diagnose(delay_log / "log.csv", threads=2, progress=lines.append)
    assert d.cause == j["cause"] == "input_delay"
    # The same computation on the same log: equal up to the rounding of another build of
    # the same code (the test build's tool against the package's release build).
    assert d.parameters.keys() == j["parameters"].keys()
    for k, v in j["parameters"].items():
        assert d.parameters[k] == pytest.approx(v, rel=1e-9)
        assert d.uncertainty[k] == pytest.approx(j["uncertainty"][k], rel=1e-6)
    assert d.error_after == pytest.approx(j["error_after"], rel=1e-9)
    assert lines, "progress lines reach the callback"
    # The hidden truth within 3σ.
    truth = json.load(open(delay_log / "truth.json"))["effects"][0]["parameters"]["delay_s"]
    (cause,) = d.causes
    assert abs(cause.parameters["delay_s"] - truth) < 3 * cause.uncertainty["delay_s"] + 1e-12
    assert set(d.residuals) >= {"t"}


def test_diagnose_takes_a_dataframe_and_a_dict(delay_log):
    g = dmech.wip.generate("input_delay", seed=2, duration=10)
    from_path = dmech.wip.diagnose(delay_log / "log.csv", threads=2, max_effects=1)
    from_frame = dmech.wip.diagnose(g.to_pandas(), threads=2, max_effects=1)
    from_dict = dmech.wip.diagnose(g.columns, threads=2, max_effects=1)
    for d in (from_frame, from_dict):
        assert d.cause == from_path.cause
        for k, v in from_path.parameters.items():
            # log.csv prints 8 significant digits; the columns carry the same numbers.
            assert d.parameters[k] == pytest.approx(v, rel=1e-9)


def test_a_malformed_log_is_refused_with_its_line():
    with pytest.raises(dmech.BadInputError, match="missing column 't'"):
        dmech.wip.diagnose({"uR": [0.0, 1.0]})
    with pytest.raises(dmech.BadInputError, match="line"):
        dmech.wip.diagnose({"t": [0.0, 0.005, 0.0], "uR": [0, 0, 0], "uL": [0, 0, 0],
                            "alpha": [0, 0, 0]})
