"""What the tests share: the command-line tool they compare the package with.

The package must report what the command line reports for the same request. The tests
run the `wip` binary of the same checkout: ``DMECH_BIN_DIR`` names its folder (``.ci/run``
sets it to the test build's); otherwise ``target/release`` or ``target/debug`` of the
repository.
"""

import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _bin_dir() -> Path:
    env = os.environ.get("DMECH_BIN_DIR")
    if env:
        return Path(env)
    for profile in ("release", "debug"):
        d = REPO / "target" / profile
        if (d / "wip").exists():
            return d
    raise RuntimeError("no wip binary: build it (cargo build --release) or set DMECH_BIN_DIR")


@pytest.fixture(scope="session")
def cli():
    """Run a robot's tool: ``cli("wip", "plan", "eight", "--out", d)`` -> CompletedProcess."""
    bin_dir = _bin_dir()

    def run(tool, *args):
        return subprocess.run(
            [str(bin_dir / tool), *map(str, args)], capture_output=True, text=True
        )

    return run


def read_summary(folder) -> dict:
    with open(Path(folder) / "summary.json", encoding="utf-8") as f:
        return json.load(f)
