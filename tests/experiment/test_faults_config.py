"""Fault injection, configuration: every numeric field, generated from the schema, not listed.

The walk below is the test's own (it does not use :mod:`amex.core.schema`): it enumerates every
number
of a :class:`~amex.experiment.config.RunConfig`, with each registered method's config, including
numbers in
lists and nested nodes, so a field added later is tested without being named here.
"""

import copy
import dataclasses
import math

import pytest

from amex.app.checks import validate_command_line
from amex.app.compose import load_config
from amex.core.errors import ConfigError, UsageError
from amex.experiment.config import RunConfig, validate
from amex.experiment.runner import preflight
from amex.methods import BUILTIN_METHODS, METHODS
from amex.robot import load_robot


def _config(method: str) -> RunConfig:
    """Task 1 with ``method``; the robot's lists filled in (empty ones take catalogue values)."""
    config = RunConfig(task=1)
    config.method = METHODS[method].config_class()
    robot = load_robot(config.robot)
    config.robot.q0 = robot.q0.tolist()
    config.robot.torque_limit = robot.torque_limit.tolist()
    config.robot.velocity_limit = robot.velocity_limit.tolist()
    return config


def _numbers(node, path=""):
    """(dotted path, getter-free setter) of every number below ``node``."""
    if dataclasses.is_dataclass(node):
        for f in dataclasses.fields(node):
            yield from _numbers(getattr(node, f.name), f"{path}{f.name}.")
    elif isinstance(node, list):
        for i, item in enumerate(node):
            yield from _numbers(item, f"{path[:-1]}[{i}].")
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield path[:-1]


def _set(config, path: str, value) -> None:
    *parents, last = path.replace("[", ".[").split(".")
    node = config
    for name in parents:
        node = node[int(name[1:-1])] if name.startswith("[") else getattr(node, name)
    if last.startswith("["):
        node[int(last[1:-1])] = value
    else:
        setattr(node, last, value)


# amex's own methods: the suite must not depend on what else is installed (plugins)
CASES = sorted({(m, p) for m in BUILTIN_METHODS for p in _numbers(_config(m))})


def test_the_generated_cases_cover_every_config_group():
    groups = {p.split(".")[0].split("[")[0] for _, p in CASES}
    assert {"method", "scenario", "plan", "controller", "perception", "mismatch"} <= groups
    assert {"prediction", "robot", "inner_hz", "max_time"} <= groups
    assert len(CASES) > 100


# The generated cases run as one test per rule and method (each lists every case that fails),
# so that the count of tests counts rules, not the ~1,800 numbers they are tried on.
METHOD_NAMES = sorted({m for m, _ in CASES})


def _non_finite_problem(method: str, path: str, bad: float) -> str:
    config = _config(method)
    _set(config, path, bad)
    try:
        validate(config)
    except ConfigError as e:
        shown = path.replace("method.", "") if path.startswith("method.") else path
        if "valid" in str(e) and shown.split("[")[0] in str(e):
            return ""
        return f"{path}={bad}: message does not name it: {e}"
    return f"{path}={bad} accepted"


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_a_non_finite_number_anywhere_is_rejected_naming_its_key(method):
    paths = [p for m, p in CASES if m == method]
    problems = [
        problem
        for path in paths
        for bad in (math.nan, math.inf, -math.inf)
        if (problem := _non_finite_problem(method, path, bad))
    ]
    assert problems == [], f"{len(problems)} of {3 * len(paths)} cases: {problems[:10]}"


SCALARS = [(m, p) for m, p in CASES if "[" not in p]


def _negative_problem(method: str, path: str) -> str:
    config = _config(method)
    field_default = copy.deepcopy(config)
    _set(config, path, -1)
    try:
        validate(config)
    except ConfigError as e:
        return "" if path.split(".")[-1] in str(e) else f"{path}=-1: message does not name it: {e}"
    allowed = {"plane_offset", "measurement_std"}  # declared signed in their schema
    if path.split(".")[-1] in allowed:
        return ""
    return f"{path}=-1 accepted (default {field_default})"


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_a_negative_scalar_is_rejected_unless_the_field_allows_it(method):
    paths = [p for m, p in SCALARS if m == method]
    problems = [problem for path in paths if (problem := _negative_problem(method, path))]
    assert problems == [], f"{len(problems)} of {len(paths)} cases: {problems[:10]}"


@pytest.mark.parametrize(
    ("overrides", "needle"),
    [
        (["+scenario.scal=0.5"], "'scenario.scal'"),
        (["+foo=1"], "'foo'"),
        (["method=dmp", "+method.n_basiss=5"], "'method.n_basiss'"),
    ],
)
def test_an_unknown_key_is_an_error_with_or_without_plus(overrides, needle):
    with pytest.raises(ConfigError, match="unknown config key") as info:
        load_config(overrides)
    assert needle in str(info.value)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["method=dmp", "method.n_basis=1"], "method.n_basis=1"),
        (["method=amex", "method.eq9=foo"], "method.eq9='foo'"),
        (["method=amex", "method.n_control=2"], "method.n_control=2"),
        (["method=cr", "method.knot_dt=0"], "method.knot_dt=0"),
        (["plan.acceleration=-1"], "plan.acceleration=-1"),
        (["plan.dt=1e-9"], "plan.dt"),
        (["robot.q0=[0,0]"], "robot.q0=[0.0, 0.0]"),
        (["robot.q0=[0,0,0,nan,0,0,0]"], "robot.q0[3]=nan"),
        (["max_time=inf"], "max_time=inf"),
        (["inner_hz=inf"], "inner_hz=inf"),
        (["controller.reg=-1"], "controller.reg=-1"),
        (["controller.col.kp=-5"], "controller.col.kp=-5"),
        (["mismatch.mass_scale=inf"], "mismatch.mass_scale=inf"),
        (["scenario.box_size=[nan,0.8,1.8]"], "scenario.box_size[0]=nan"),
        (["method=track", "method.eq9=foo"], "valid keys of method: name, pos, dir"),
        (["-m", "hydra.launcher.n_jobs=0"], "hydra.launcher.n_jobs=0"),
        (["hydra/launcher=nope"], "hydra/launcher='nope'"),
        (["experiment=nope"], "experiment='nope'"),
        (["hydra.run.dir="], "hydra.run.dir=''"),
    ],
)
def test_bad_values_are_refused_before_any_directory_exists(tmp_path, monkeypatch, argv, needle):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UsageError) as info:
        validate_command_line([*argv, "episodes=1"])
    message = str(info.value)
    assert needle in message and "valid" in message, message
    assert "\n" not in message
    assert list(tmp_path.iterdir()) == []


def test_a_run_directory_that_is_a_file_or_unwritable_is_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "plain").write_text("a file")
    for argv, needle in (
        ([f"hydra.run.dir={tmp_path / 'plain'}"], "it is a file"),
        ([f"hydra.run.dir={tmp_path / 'plain' / 'run'}"], "plain is a file"),
        (["-m", f"hydra.sweep.dir={tmp_path / 'plain'}"], "it is a file"),
    ):
        with pytest.raises(UsageError, match=needle):
            validate_command_line([*argv, "episodes=1"])


def test_a_run_directory_on_a_read_only_file_system_is_refused(read_only_dir, monkeypatch):
    monkeypatch.chdir(read_only_dir.parent)
    with pytest.raises(UsageError, match="not writable"):
        validate_command_line([f"hydra.run.dir={read_only_dir / 'run'}", "episodes=1"])


@pytest.mark.parametrize(
    ("method", "param", "value"),
    [("dmp", "n_basis", 1), ("amex", "eq9", "foo"), ("amex", "n_control", 2), ("cr", "knot_dt", 0)],
)
def test_a_bad_method_parameter_is_named_by_the_validation_before_a_run(method, param, value):
    config = _config(method)
    setattr(config.method, param, value)
    with pytest.raises(ConfigError, match=rf"invalid method.{param}=.*; valid: "):
        validate(config)  # the method config's own validate()


def test_preflight_builds_the_method_and_names_a_parameter_that_does_not_fit_the_plan():
    config = _config("amex")
    config.method.n_control = 500
    validate(config)  # the schema alone cannot know the plan's 401 samples
    with pytest.raises(ConfigError, match=r"invalid method.n_control=500; valid: 0 or 3..401"):
        preflight(config)


def test_a_sweep_job_directory_of_another_configuration_is_refused_untouched(tmp_path, monkeypatch):
    from amex.experiment.runner import run

    sweep = tmp_path / "sweep"
    config = _config("track")
    config.task, config.episodes, config.max_time, config.seed = 1, 1, 0.2, 1
    run(config, sweep / "task1_track_seed0")  # recorded with seed 1 where seed 0 belongs
    before = {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file()}
    monkeypatch.chdir(tmp_path)
    argv = ["-m", "task=0,1", "method=track", "episodes=1", f"hydra.sweep.dir={sweep}"]
    with pytest.raises(UsageError, match="another configuration"):
        validate_command_line(argv)
    assert {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file()} == before
