"""``python -m amex.app.warm`` leaves nothing to compile for a run, logged or not (slow: ~1 min)."""

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

# A logged episode, then the cache misses of every compiled function amex loaded: a miss is a
# kernel the run compiled because the cache had no entry for it.
_RUN = """
import sys, tempfile
from pathlib import Path
from amex.app.compose import load_config
from amex.experiment.runner import prepare, run_one
config = load_config(["method=amex", "task=3", "max_time=0.05"])
run_one(config, prepare(config), 0, Path(tempfile.mkdtemp()) / "episode.mcap")
from numba.core.registry import CPUDispatcher
missed = sorted(
    f"{name}.{attr}"
    for name, module in list(sys.modules.items()) if name.startswith("amex.") and module
    for attr, value in vars(module).items()
    if isinstance(value, CPUDispatcher) and value.stats.cache_misses
)
print("compiled:", " ".join(missed))
"""


def _python(code_or_module: list[str], cache: str) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    done = subprocess.run(
        [sys.executable, *code_or_module], env=env, capture_output=True, text=True, check=True
    )
    return done.stdout


def test_a_logged_run_after_warm_compiles_no_kernel(tmp_path):
    cache = str(tmp_path / "numba")
    cold = _python(["-c", _RUN], cache)
    assert cold.split("compiled:")[1].split(), "an empty cache compiles (the check can fail)"
    cache = str(tmp_path / "numba-warm")
    _python(["-m", "amex.app.warm", "amex"], cache)
    warm = _python(["-c", _RUN], cache)
    assert warm.strip() == "compiled:", warm
