"""A single run of ``amex-run`` composed once: Hydra's run of the job, on the checked config.

``hydra.main`` composes the command line twice before its job starts (once to read
``hydra.mode``, once to run), and ``amex-run`` composes it a third time to check it first
(:mod:`amex.app.checks`): ~0.1 s of CPU each, in every process. For a single run (no ``-m``, no
informational flag) :func:`main_hydra` sets up Hydra as ``hydra.main`` does (the same search path,
job name and parser), the checks compose through it, and :func:`run_composed` runs the job on that
composition as Hydra's own ``run`` does: its callbacks, its output directory, ``.hydra/`` record
and logging. The run directory's files are the same as ``hydra.main``'s, ``hydra.mode=RUN`` in the
record included. A sweep (``-m``) is handed to Hydra's ``multirun`` without the composition that
only reads ``hydra.mode`` (:func:`run_sweep`); informational flags (``--cfg``, ``--info``, ...)
still go through ``hydra.main``.

This uses Hydra's internal set-up functions (``hydra._internal``, pinned in ``pyproject.toml``);
``tests/app/test_launch.py`` compares a run's ``.hydra/`` record with ``hydra.main``'s.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

TaskFunction = Callable[[Any], Any]
#: Hydra's ``version_base`` of amex (``hydra.main`` and the compose API are given the same).
VERSION_BASE = "1.3"


def main_hydra(task_function: TaskFunction, config_dir: str, argv: list[str]) -> tuple[Any, Any]:
    """Hydra set up for ``argv`` as ``hydra.main(config_path=config_dir, version_base="1.3")``.

    Returns the ``Hydra`` object and Hydra's parse of ``argv`` (``overrides``, ``config_name``,
    ...). Nothing is composed and no directory is created.
    """
    from hydra import version
    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import (
        create_automatic_config_search_path,
        detect_calling_file_or_module_from_task_function,
        detect_task_name,
        get_args_parser,
    )
    from hydra.core.config_search_path import SearchPathQuery
    from hydra.core.global_hydra import GlobalHydra

    version.setbase(VERSION_BASE)  # as hydra.main(version_base=...) sets it
    args = get_args_parser().parse_args(argv)
    calling_file, calling_module = detect_calling_file_or_module_from_task_function(task_function)
    search_path = create_automatic_config_search_path(calling_file, calling_module, config_dir)
    if args.config_dir is not None:  # checked to be a directory (amex.app.compose)
        search_path.prepend(
            provider="command-line",
            path=f"file://{os.path.abspath(args.config_dir)}",
            anchor=SearchPathQuery(provider="schema"),
        )
    GlobalHydra.instance().clear()
    task_name = detect_task_name(calling_file, calling_module)
    hydra = Hydra.create_main_hydra2(task_name=task_name, config_search_path=search_path)
    return hydra, args


def compose_run(hydra: Any, config_name: str, overrides: list[str]) -> Any:
    """The run's config (Hydra's part included) as ``Hydra.run`` composes it.

    ``hydra.mode`` left unset by the configs is ``RUN``, recorded among Hydra's overrides as
    ``hydra.main`` records it.
    """
    from hydra.types import RunMode
    from omegaconf import open_dict, read_write

    cfg = hydra.compose_config(
        config_name=config_name,
        overrides=list(overrides),
        with_log_configuration=True,
        run_mode=RunMode.RUN,
    )
    if cfg.hydra.mode is None:
        with read_write(cfg), open_dict(cfg):
            cfg.hydra.mode = RunMode.RUN
            cfg.hydra.overrides.hydra.append("hydra.mode=RUN")
    return cfg


def single_run(cfg: Any) -> bool:
    """Whether ``cfg`` (None: not composed for a single run) is one run's, to run composed.

    A config of the user's that sets ``hydra.mode: MULTIRUN`` is left to ``hydra.main``.
    """
    from hydra.types import RunMode

    return cfg is not None and cfg.hydra.mode == RunMode.RUN


def run_sweep(hydra: Any, args: Any, task_function: TaskFunction) -> None:
    """Hydra's ``multirun`` of the command line (``-m``), as ``hydra.main`` runs it; clear Hydra."""
    from hydra.core.global_hydra import GlobalHydra

    try:
        hydra.multirun(
            config_name=args.config_name or "config",
            task_function=task_function,
            overrides=[*args.overrides, "hydra.mode=MULTIRUN"],
        )
    finally:
        GlobalHydra.instance().clear()


def run_composed(hydra: Any, cfg: Any, config_name: str, task_function: TaskFunction) -> None:
    """Run ``task_function`` on the composed ``cfg`` as Hydra's ``run`` does, and clear Hydra.

    The job's exception, if any, is raised here (``HYDRA_FULL_ERROR`` semantics).
    """
    from hydra._internal.callbacks import Callbacks
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.utils import run_job
    from hydra.types import HydraContext

    try:
        callbacks = Callbacks(cfg)
        callbacks.on_run_start(config=cfg, config_name=config_name)
        ret = run_job(
            hydra_context=HydraContext(config_loader=hydra.config_loader, callbacks=callbacks),
            task_function=task_function,
            config=cfg,
            job_dir_key="hydra.run.dir",
            job_subdir_key=None,
            configure_logging=True,
        )
        callbacks.on_run_end(config=cfg, config_name=config_name, job_return=ret)
        _ = ret.return_value  # the job's exception
    finally:
        GlobalHydra.instance().clear()
