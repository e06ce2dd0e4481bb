"""``amex-run``: check the whole command line, then hand it to Hydra.

Every configuration the command line asks for is composed and validated first
(:mod:`amex.app.checks`); any bad value is one line on stderr and exit code 2 before Hydra creates
a run directory. Only then does Hydra run the job(s) (:func:`amex.app.job.task`). A job's failure
(a full disk, a locked directory) is one line too, with the number of episodes kept; Ctrl-C and
SIGTERM stop the run or the whole sweep, workers included, and say that the same command
resumes. ``AMEX_DEBUG=1`` shows tracebacks.

A single run that finished ends without the interpreter's teardown (:func:`main`): its exit
handlers run (logging's flush and close among them), the standard streams are flushed, and the
process exits with code 0, skipping the freeing of every module and object one by one, ~0.02 s of
CPU per process (``make bench``, start-up). Where a thread other than the main one is alive, or
for a sweep, or after an error, the process exits as usual.
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
    "--help",
    "-h",
    "--hydra-help",
    "--info",
    "-i",
    "--cfg",
    "-c",
    "--shell-completion",
    "-sc",
}


def flags_first(argv: list[str]) -> list[str]:
    """``argv`` with ``-m`` and the config flags (with their values) before the overrides.

    Hydra's parser takes the overrides as one run of positional arguments, so an override after
    a flag (``task=1 --config-dir my_conf seed=2``) would be refused; the order of the overrides
    is kept.
    """
    from amex.app.compose import FLAGS_WITH_VALUE

    flags: list[str] = []
    rest: list[str] = []
    args = iter(argv)
    for arg in args:
        if arg in ("-m", "--multirun"):
            flags.append(arg)
        elif arg in FLAGS_WITH_VALUE:
            flags += [arg, next(args, "")]
        elif arg.partition("=")[0] in FLAGS_WITH_VALUE:
            flags.append(arg)
        else:
            rest.append(arg)
    return flags + rest


def run_main() -> None:
    """``amex-run``: validate the command line, then hand it to Hydra."""
    from amex.app.heap import hold, settle

    hold()  # no cyclic collections during start-up (amex.app.heap); the job settles the heap
    from amex.app.compose import CONF_DIR, PROG
    from amex.app.processes import LAUNCHER_PID, signals_raise

    argv = flags_first(sys.argv[1:])
    sys.argv[1:] = argv  # Hydra's parser wants its flags before the overrides; accept them anywhere
    multirun_flags = [a for a in argv if a in ("-m", "--multirun")]
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
            from amex.app.compose import register_schemas
            from amex.app.job import task
            from amex.app.launch import VERSION_BASE

            register_schemas()
            if not INFORMATIONAL.intersection(argv):
                from amex.app.checks import launch_lock, validate_command_line
                from amex.app.launch import main_hydra, run_composed, run_sweep, single_run
                from amex.app.reaper import start_reaper

                # a single run is composed once, by the Hydra that runs it (amex.app.launch)
                single = not multirun_flags
                run_hydra, args = main_hydra(task, CONF_DIR, argv) if single else (None, None)
                try:
                    checked = validate_command_line(argv, run_hydra)
                    _lock = launch_lock(checked.dirs, bool(multirun_flags))
                except UsageError as e:
                    if debug:
                        raise
                    fail(str(e))
                os.environ[LAUNCHER_PID] = str(os.getpid())  # sweep workers stop with this process
                if args is not None and single_run(checked.cfg):
                    run_composed(run_hydra, checked.cfg, args.config_name or "config", task)
                    return
                if not single:
                    settle()  # a sweep's launcher: the collector on again for the whole sweep
                    start_reaper()  # ends what a SIGKILL to this process leaves (amex.app.reaper)
                    run_sweep(*main_hydra(task, CONF_DIR, argv), task)
                    return
            import hydra

            settle()
            main = hydra.main(CONF_DIR, config_name="config", version_base=VERSION_BASE)(task)
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


def main() -> None:
    """``amex-run`` (the console script): :func:`run_main`, then a single run exits quickly."""
    run_main()
    if not {"-m", "--multirun"}.intersection(sys.argv[1:]):
        exit_quickly()


def exit_quickly() -> None:
    """Exit with code 0 after the exit handlers, without the interpreter's teardown (notes).

    Returns (so the interpreter exits as usual) where that could lose anything: another thread
    is alive (the interpreter would wait for it), the exit handlers cannot be run here, or a
    standard stream does not flush.
    """
    import atexit
    import threading

    run_handlers = getattr(atexit, "_run_exitfuncs", None)  # CPython's, since 2.x
    if threading.active_count() > 1 or run_handlers is None:
        return
    run_handlers()
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):  # a closed or broken stream: the usual exit reports it
        return
    os._exit(0)
