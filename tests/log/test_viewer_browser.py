"""Logs open in a real browser viewer: Foxglove Studio 1.48 in headless Chromium (make test-viewer).

``make test-viewer`` installs Debian's chromium and the npm packages of ``tests/viewer/`` (Foxglove
Studio 1.48's ``@foxglove/studio-base``, React 17, playwright-core), then runs these tests: a
logged episode of each method is served by ``amex-log view``'s server and opened in the local
Studio with its layout; ``tests/viewer/check.mjs`` waits until every topic of the log is listed and
reads the player problems. Not in the default suite (it needs chromium and node packages).
"""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log import read_log
from amex.log.serve import STUDIO_DIR, LogServer
from amex.methods import get_method

pytestmark = pytest.mark.viewer
CHECK = STUDIO_DIR / "check.mjs"


@pytest.fixture(scope="module", autouse=True)
def _viewer_installed():
    studio = STUDIO_DIR / "node_modules" / "@foxglove" / "studio-base" / "assets" / "index.js"
    if not (studio.is_file() and shutil.which("node") and Path("/usr/bin/chromium").exists()):
        pytest.fail("the viewer is not installed: run `make test-viewer`, which installs it")


@pytest.mark.parametrize(("task", "method"), [(4, "amex"), (3, "dmp"), (4, "cr")])
def test_log_opens_in_foxglove_studio_with_every_topic_and_no_problems(tmp_path, task, method):
    config = RunConfig(task=task, max_time=3.0)
    config.method = get_method(method).config_class()
    path = tmp_path / f"task{task}_{method}.mcap"
    run_one(config, prepare(config), 0, path)
    data = read_log(path)
    topics = sorted(t for t, c in data.channels.items() if c.message_count)
    screenshot = tmp_path / "studio.png"
    with LogServer(data, port=0) as server:
        assert server.urls.studio is not None
        proc = subprocess.run(
            [
                "node",
                str(CHECK),
                server.urls.studio,
                "--topics",
                ",".join(topics),
                "--screenshot",
                str(screenshot),
            ],  # fmt: skip
            capture_output=True,
            text=True,
            timeout=240,
        )
    assert proc.returncode in (0, 1), proc.stderr
    report = json.loads(proc.stdout)
    assert report["missing"] == [], report
    assert report["problems"] == [], report
    assert report["pageErrors"] == [] and report["failedRequests"] == [], report
    assert report["urdfLoaded"], report
    assert screenshot.stat().st_size > 50_000
