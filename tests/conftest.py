import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def campaign():
    from straylight.config import load_campaign

    return load_campaign(REPO / "config" / "config.yaml")


def run_cli(*args, cwd=REPO, timeout=120):
    """Run the CLI in a subprocess, as a user would; returns CompletedProcess."""
    env = dict(os.environ)
    return subprocess.run(
        [sys.executable, "-m", "straylight.cli", *map(str, args)],
        cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env,
    )
