"""The reports' own reading of sweeps: the override parser, and the jobs it finds in each study."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from analysis.overrides import OverrideError, job_of, normalized, parse, product, value_of
from analysis.sweep import declared_jobs

CONF = Path(__file__).resolve().parents[2] / "conf"
STUDIES = sorted(p.stem for p in (CONF / "study").glob("*.yaml"))


def test_a_comma_list_is_a_sweep_but_not_inside_brackets_or_quotes():
    assert parse("method=amex,dmp") == ("method", ["amex", "dmp"])
    assert parse("scenario.box_grid=[3,5,10]") == ("scenario.box_grid", ["[3,5,10]"])
    assert parse("+a.b='x,y'") == ("a.b", ["'x,y'"])
    assert parse("~prediction") == ("~prediction", [""])


def test_a_sweep_function_is_refused_with_the_override_named():
    with pytest.raises(OverrideError, match="range"):
        parse("seed=range(0,3)")


def test_the_product_keeps_a_key_in_its_first_place_with_its_last_values():
    jobs = product(["method=amex,dmp,cr", "task=1,2", "method=amex"])
    assert jobs == [{"method": "amex", "task": "1"}, {"method": "amex", "task": "2"}]


def test_values_compare_as_yaml_reads_them():
    assert value_of("False") is False and value_of("'false'") == "false"
    assert value_of("0") == value_of("0.0") == 0 and value_of("none") == "none"
    run = job_of(["prediction.enabled=False", "perception.noise_std=0.0", "study=robustness"])
    job = {"prediction.enabled": "false", "perception.noise_std": "0", "study": "robustness"}
    assert normalized(run) == normalized(job)


@pytest.mark.parametrize("study", STUDIES)
def test_the_reports_find_exactly_the_jobs_the_sweeper_launches(study):
    from amex.app.checks import sweep_settings
    from amex.app.sweeps import sweep_jobs

    params, grids, shards, _ = sweep_settings([f"study={study}"], [])
    jobs = sweep_jobs(params, grids, [f"study={study}"], shards)
    launched = [normalized(job_of(job)) for job in jobs]
    sweeper = yaml.safe_load((CONF / "study" / f"{study}.yaml").read_text())["hydra"]["sweeper"]
    found = []
    for _, job in declared_jobs(sweeper, [f"study={study}"]):
        if normalized(job) not in found:
            found.append(normalized(job))
    assert found == launched
