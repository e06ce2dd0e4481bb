"""``amex-run --help``: what can be run, with which options, and where the results go.

Everything listed is discovered, not typed in twice: methods from the registry (built-ins and
plugins; ``schema_*`` are the typed schemas behind them, not choices), robots, experiments and
studies from ``conf/robot/*.yaml``, ``conf/experiment/*.yaml`` and ``conf/study/*.yaml`` (each
described by the first line of its header comment), the options with their defaults and units
from the comments of ``conf/config.yaml``, and the output directories from its ``hydra`` section.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import yaml

TASKS = {
    0: "the reference scene: no offset, no motion, no obstacle",
    1: "offset goal: a grid in a box around the reference goal (static)",
    2: "moving goal: starts at the reference goal, moves for 70 % of T_ref",
    3: "moving goal on a plane beyond the box, static sphere obstacle in the way",
    4: "as 3, the obstacle moves too",
}
_OPTION = re.compile(r"^(\w+):\s*([^#\s][^#]*?)?\s*(?:#\s*(.*))?$")


def describe(path: Path) -> str:
    """The first sentence of a YAML file's header comment (after ``# @package``)."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        text = line.lstrip("#").strip()
        if text.startswith("@package"):
            continue
        lines.append(text)
    text = " ".join(lines)
    depth = 0
    for i, char in enumerate(text):  # the first clause: up to . : ; outside parentheses
        depth += (char == "(") - (char == ")")
        if depth == 0 and char in ".:;" and (i + 1 == len(text) or text[i + 1] == " "):
            text = text[:i]
            break
    if len(text) > 90:  # too long: without its parenthetical remarks
        text = re.sub(r"\s*\([^()]*\)", "", text)
    return text if len(text) <= 90 else text[:87].rsplit(" ", 1)[0] + "..."


def _options(config_yaml: Path) -> tuple[list[tuple[str, str, str]], list[tuple[str, str]]]:
    """Top-level ``key: value  # comment`` options and ``group:  # comment`` sections."""
    options, groups = [], []
    for line in config_yaml.read_text().splitlines():
        m = _OPTION.match(line)
        if not m or line.startswith(("defaults", "hydra")):
            continue
        key, value, comment = m.group(1), m.group(2), m.group(3) or ""
        if value is None:
            groups.append((key, comment))
        else:
            options.append((key, value, comment))
    return options, groups


def _table(rows: list[tuple[str, str]], indent: int = 2) -> list[str]:
    width = max((len(a) for a, _ in rows), default=0) + 2
    out = []
    for a, b in rows:
        wrapped = textwrap.wrap(b, 98 - indent - width) or [""]
        out.append(" " * indent + a.ljust(width) + wrapped[0])
        out += [" " * (indent + width) + w for w in wrapped[1:]]
    return out


def _pattern(text: str) -> str:
    """A Hydra directory pattern with its interpolations as ``<names>``."""
    for hydra_name, name in (("${now:%Y-%m-%d}", "date"), ("${now:%H-%M-%S.%f}", "time"),
                             ("${method.name}", "method")):  # fmt: skip
        text = text.replace(hydra_name, f"<{name}>")
    text = text.replace("${amex.shard:${shard},${shards}}", "[_shard<I>of<K>]")
    return re.sub(r"\$\{(\w+)\}", r"<\1>", text)


def _indent(text: str) -> list[str]:
    return textwrap.wrap(text, 96, initial_indent="      ", subsequent_indent="      ")


def _options_of(conf_dirs: list[Path], group: str, recursive: bool = False) -> list[Path]:
    """The YAML files of a config group, the first directory's winning (``--config-dir``'s)."""
    found: dict[str, Path] = {}
    for conf_dir in conf_dirs:
        base = conf_dir / group
        for path in sorted(base.rglob("*.yaml") if recursive else base.glob("*.yaml")):
            found.setdefault(path.relative_to(base).with_suffix("").as_posix(), path)
    return [found[name] for name in sorted(found)]


def _methods(dirs: list[Path]) -> list[tuple[str, str]]:
    """Every registered method (built-ins by their config's header, plugins by their class)."""
    from amex.methods import BUILTIN_METHODS, METHODS

    conf_dir = dirs[-1]
    rows = []
    for name in sorted(METHODS):
        yaml_file = conf_dir / "method" / f"{name}.yaml"
        if name in BUILTIN_METHODS and yaml_file.exists():
            text = describe(yaml_file)
        else:
            doc = (METHODS[name].__doc__ or "").strip().splitlines()
            text = (doc[0] if doc else "") + f" (plugin: {METHODS[name].__module__})"
        rows.append((name, text))
    users = {p.stem: p for p in _options_of(dirs[:-1], "method")}
    return rows + [(n, describe(p) + " (yours)") for n, p in users.items() if n not in METHODS]


def _listed(dirs: list[Path], group: str, recursive: bool = False) -> list[tuple[str, str]]:
    """The options of a config group from every directory, the user's marked as theirs."""
    base_of = {p: d / group for d in dirs for p in _options_of([d], group, recursive)}
    rows = []
    for path in _options_of(dirs, group, recursive):
        name = path.relative_to(base_of[path]).with_suffix("").as_posix()
        mine = "" if base_of[path].parent == dirs[-1] else " (yours)"
        rows.append((name, describe(path) + mine))
    return rows


def _outputs(composed: dict) -> list[str]:
    """Where runs and sweeps write, from the primary config's ``hydra`` section."""
    hydra = composed.get("hydra", {})
    run_dir = hydra.get("run", {}).get("dir", "")
    sweep = hydra.get("sweep", {})
    sweep_dir = f"{sweep.get('dir', '')}/{sweep.get('subdir', '')}"
    return [
        "outputs:",
        f"  {_pattern(run_dir)}/",
        *_indent(
            "one run, printed as the last line; hydra.run.dir=DIR chooses it. It holds "
            "episodes.csv (a row per episode), summary.json (mean and 2 std of every metric), "
            "run.log, .hydra/ (the exact configuration) and, with log=full, "
            "logs/episode_NNN.mcap. Running again into the same directory resumes."
        ),
        f"  {_pattern(sweep_dir)}/",
        *_indent("each job of a -m sweep; hydra.sweep.dir=DIR chooses the sweep's directory."),
        "  then",
        *_indent(
            "make table RUNS=DIR (Fig. 5 as tables), make figures RUNS=DIR (as plots); "
            "amex-log view|video|plot FILE.mcap (a logged episode)"
        ),
    ]


def help_text(conf_dirs: Path | list[Path], prog: str = "amex-run") -> str:
    """The whole ``--help`` text; ``conf_dirs``: the user's config directories, then amex's."""
    dirs = [conf_dirs] if isinstance(conf_dirs, Path) else list(conf_dirs)
    config_yaml = dirs[-1] / "config.yaml"  # amex's own primary config
    options, groups = _options(config_yaml)
    composed = yaml.safe_load(config_yaml.read_text())
    default_robot = next(
        (d["robot"] for d in composed["defaults"] if isinstance(d, dict) and "robot" in d), ""
    )
    lines = [
        f"{prog}: the benchmark of Englert & Toussaint (IROS 2014): AMEX, DMPs and continuous",
        "replanning on identical scenes. Arguments are Hydra overrides KEY=VALUE.",
        "",
        f"usage: {prog} [KEY=VALUE ...]             one run (e.g. task=3 method=amex episodes=20)",
        f"       {prog} -m KEY=A,B [KEY=VALUE ...]  a sweep: every combination, one job per core",
        f"       {prog} -m ... shards=K             ... every cell split over K jobs",
        f"       {prog} --cfg job [KEY=VALUE ...]   print the composed configuration",
        f"       {prog} --config-dir DIR ...        with your own experiment/, robot/, ... configs",
        f"       {prog} --hydra-help                Hydra's own flags",
        "",
        "tasks (task=N):",
        *_table([(str(k), v) for k, v in TASKS.items()]),
        "",
        "methods (method=NAME; parameters method.FIELD=..., conf/method/NAME.yaml):",
        *_table(_methods(dirs)),
        "",
        f"robots (robot=NAME, default {default_robot}; conf/robot/NAME.yaml):",
        *_table(_listed(dirs, "robot")),
        "",
        "experiments (experiment=NAME: a named set of overrides, conf/experiment/NAME.yaml):",
        *_table(_listed(dirs, "experiment", recursive=True) or [("(none)", "")]),
        "",
        "studies (-m study=NAME: a sweep, its cells in conf/study/NAME.yaml; analysis/NAME.py):",
        *_table(_listed(dirs, "study") or [("(none)", "")]),
        "",
        "main options (default value, unit and meaning):",
        *_table([(f"{k}={v}", c) for k, v, c in options]),
        *_table([(f"{k}.*", c or "see --cfg job") for k, c in groups]),
        *_table(
            [
                ("robot.*", "the arm: robot.q0, robot.urdf, ... (conf/robot/NAME.yaml)"),
                ("method.*", "the method's parameters (conf/method/NAME.yaml)"),
            ]
        ),  # fmt: skip
        "",
        *_outputs(composed),
        "",
        "Bad input gets one line on stderr and exit code 2; AMEX_DEBUG=1 shows tracebacks.",
    ]
    return "\n".join(lines) + "\n"
