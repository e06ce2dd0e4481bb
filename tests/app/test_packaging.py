"""The package as users install it: every package of the tree in the wheel, configs included."""

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _listed() -> set[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    return set(config["packages"]), config["package-dir"]


def _on_disk(base: Path, name: str, marker) -> set[str]:
    return {
        ".".join([name, *d.relative_to(base).parts]).rstrip(".")
        for d in [base, *base.rglob("*")]
        if d.is_dir() and marker(d) and "__pycache__" not in d.parts
    }


def test_every_package_and_config_directory_is_in_the_wheel():
    listed, mapped = _listed()
    code = _on_disk(ROOT / "amex", "amex", lambda d: (d / "__init__.py").is_file())
    code = {p for p in code if not p.startswith("amex._plugins")}
    configs = _on_disk(ROOT / "conf", "amex.conf", lambda d: any(d.glob("*.yaml")) or d.is_dir())
    plugins = _on_disk(
        ROOT / mapped["hydra_plugins"], "hydra_plugins", lambda d: (d / "__init__.py").is_file()
    )
    missing = (code | configs | {p for p in plugins if p != "hydra_plugins"}) - listed
    assert sorted(missing) == []
    assert mapped["amex.conf"] == "conf"
    assert mapped["amex_analysis"] == "analysis" and "analysis" not in listed  # no generic name


def test_the_packaged_configs_are_the_ones_amex_run_composes():
    from amex.app.compose import CONF_DIR

    assert Path(CONF_DIR) == ROOT / "conf"  # in a checkout; a wheel has them as amex/conf
