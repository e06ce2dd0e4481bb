"""``amex-run``: check the whole command line, then hand it to Hydra.

Every configuration the command line asks for is composed and validated first
(:mod:`amex.app.checks`); any bad value is one line on stderr and exit code 2 before Hydra creates
a run directory. Only then does Hydra run the job(s) (:func:`amex.app.job.task`). A job's failure
(a full disk, a locked directory) is one line too, with the number of episodes kept; Ctrl-C and
SIGTERM stop the run or the whole sweep, workers included, and say that the same command
resumes. ``AMEX_DEBUG=1`` shows tracebacks.
"""

from __future__ import annotations

import os

# One BLAS/OpenMP thread per process: episodes are tiny linear algebra, and sweeps run one job
# per core. Set before numpy is imported anywhere.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# No on-screen OpenGL: importing MuJoCo otherwise loads GLFW for its Renderer (~40 ms of every
# process); amex draws offscreen through mujoco.egl or mujoco.osmesa (amex.log.render), which
# this leaves alone. A MUJOCO_GL of the user's is kept.
os.environ.setdefault("MUJOCO_GL", "disable")

import sys  # noqa: E402

from amex.app.session import closing_line, fail, say  # noqa: E402  (first: the command's start)
from amex.core.errors import JobFailed, UsageError  # noqa: E402

INFORMATIONAL = {
    "--help", "-h", "--hydra-help", "--info", "-i", "--cfg", "-c", "--shell-completion", "-sc"
}


def run_main() -> None:
    """``amex-run``: validate the command line, then hand it to Hydra."""
    from amex.app.compose import CONF_DIR, PROG
    from amex.app.processes import LAUNCHER_PID, signals_raise

    multirun_flags = [a for a in sys.argv[1:] if a in ("-m", "--multirun")]
    argv = multirun_flags + [a for a in sys.argv[1:] if a not in multirun_flags]
    sys.argv[1:] = argv  # Hydra's parser wants -m before the overrides; accept it anywhere
    debug = os.environ.get("AMEX_DEBUG") == "1"
    if "--version" in argv:
        from amex import __version__

        sys.stdout.write(f"{PROG} {__version__}\n")
        return
    if "--help" in argv or "-h" in argv:
        from amex.app import compose
        from amex.app.usage import help_text

        try:
            compose.use_command_line(argv)
        except UsageError as e:
            fail(str(e))
        sys.stdout.write(help_text(compose.SOURCES.conf_dirs(), PROG))
        return
    from amex.app.progress import SWEEPS

    try:
        with signals_raise():
            if not INFORMATIONAL.intersection(argv):
                from amex.app.checks import launch_lock, validate_command_line

                try:
                    _lock = launch_lock(validate_command_line(argv), bool(multirun_flags))
                except UsageError as e:
                    if debug:
                        raise
                    fail(str(e))
            import hydra

            from amex.app.compose import register_schemas
            from amex.app.job import task

            register_schemas()
            main = hydra.main(config_path=CONF_DIR, config_name="config", version_base="1.3")(task)
            os.environ[LAUNCHER_PID] = str(os.getpid())  # sweep workers stop with this process
            os.environ["HYDRA_FULL_ERROR"] = "1"  # Hydra re-raises its errors, we print one line
            main()
    except (JobFailed, KeyboardInterrupt, Exception) as e:
        if debug:
            raise
        for callback in SWEEPS:  # stop the sweep's progress bar before the last line
            callback.stop()
        line, code = closing_line(e)
        say(line)
        raise SystemExit(code) from None
