"""amex-run's quick exit after a single run: nothing written is lost, nothing waited for is cut."""

import json
import subprocess
import sys
import textwrap

import pytest

from amex.app import cli

# a run as the console script makes it, with a witness of the interpreter's shutdown (threading
# calls it before the exit handlers, os._exit never) and an exit handler registered before the run
_SCRIPT = textwrap.dedent(
    """
    import atexit, os, sys, threading
    from pathlib import Path

    threading._register_atexit(lambda: os.write(2, b"teardown ran\\n"))
    marker = Path(sys.argv.pop(1))
    atexit.register(lambda: marker.write_text("handler ran"))
    sys.argv[0] = "amex-run"
    from amex.app.cli import main
    sys.exit(main())
    """
)


def _run(tmp_path, *overrides):
    marker = tmp_path / "handler.txt"
    run_dir = tmp_path / "run"
    command = [sys.executable, "-c", _SCRIPT, str(marker), "task=0", "method=track"]
    command += ["episodes=2", "max_time=0.02", f"hydra.run.dir={run_dir}", *overrides]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    return done, marker, run_dir


def test_a_single_run_exits_quickly_with_everything_written(tmp_path):
    done, marker, run_dir = _run(tmp_path)
    assert done.returncode == 0, done.stderr
    assert "teardown ran" not in done.stderr  # the teardown was skipped ...
    assert marker.read_text() == "handler ran"  # ... but the exit handlers ran
    # both streams flushed: the run directory on stdout, the closing line on stderr
    assert done.stdout.strip() == str(run_dir) and "final time" in done.stderr
    log = (run_dir / "run.log").read_text()  # logging's handlers flushed and closed
    assert log.count("env ") == 2 and "done: success" in log.splitlines()[-1]
    assert len((run_dir / "episodes.csv").read_text().splitlines()) == 3  # header, 2 rows
    assert json.loads((run_dir / "summary.json").read_text())["episodes"] == 2


def test_a_failed_run_exits_as_usual(tmp_path):
    done, marker, _ = _run(tmp_path, "episodes=0")
    assert done.returncode == 2 and done.stderr.strip().endswith("teardown ran")
    assert marker.read_text() == "handler ran"


def test_another_live_thread_keeps_the_usual_exit():
    """With a thread the interpreter would wait for, exit_quickly returns (in a child: where it
    wrongly exits, it would end pytest itself with code 0)."""
    script = textwrap.dedent(
        """
        import threading
        from amex.app.cli import exit_quickly

        release = threading.Event()
        worker = threading.Thread(target=release.wait)
        worker.start()
        exit_quickly()  # must return: another thread is alive
        print("returned")
        release.set()
        worker.join()
        exit_quickly()  # the main thread alone: exits here, code 0
        print("not reached")
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert (done.returncode, done.stdout) == (0, "returned\n"), done.stderr


@pytest.mark.parametrize("flag", ["-m", "--multirun"])
def test_a_sweep_never_takes_the_quick_exit(monkeypatch, flag):
    monkeypatch.setattr(sys, "argv", ["amex-run", flag, "task=0"])
    monkeypatch.setattr(cli, "run_main", lambda: None)
    monkeypatch.setattr(cli, "exit_quickly", lambda: pytest.fail("a sweep exited quickly"))
    cli.main()
