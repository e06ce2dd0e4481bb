"""The configuration reference is generated from the config dataclasses: every key, with its
default, its unit and its meaning; nothing missing, nothing stale."""

from __future__ import annotations

import dataclasses
import re

import pytest

from amex.core.scaling import SCALE_KEY
from amex.experiment.config import RunConfig


def _default(f):
    if f.default is not dataclasses.MISSING:
        return f.default
    return f.default_factory()


def _expected_keys(hooks):
    """(node title, dotted key, field, default) of every field the page must show."""
    root = RunConfig()
    out = []
    for f in dataclasses.fields(RunConfig):
        out.append(("Top level", f.name, f, _default(f)))
        value = getattr(root, f.name)
        if f.name != "method" and dataclasses.is_dataclass(value):
            for g in dataclasses.fields(value):
                out.append((f"`{f.name}`", f"{f.name}.{g.name}", g, _default(g)))
    for name, cls in hooks.builtin_methods().items():
        for g in dataclasses.fields(cls.config_class):
            out.append((f"`method={name}`", f"method.{g.name}", g, _default(g)))
    return out


@pytest.fixture(scope="module")
def tables(hooks):
    """``{node title: {key: Row}}`` as the generator builds them."""
    return {n.title: {r.key.strip("`"): r for r in n.rows} for n in hooks.config_nodes()}


def test_every_config_field_has_a_row_in_its_node(hooks, tables):
    missing = [
        f"{title}: {key}"
        for title, key, _, _ in _expected_keys(hooks)
        if key not in tables.get(title, {})
    ]
    assert missing == []


def test_every_built_in_method_has_its_own_table(hooks, tables):
    from amex.methods import BUILTIN_METHODS

    assert {f"`method={name}`" for name in BUILTIN_METHODS} <= set(tables)


def test_every_row_says_what_the_key_means(hooks, tables):
    undocumented = [
        f"{title}: {key}" for title, rows in tables.items() for key, r in rows.items()
        if not r.meaning.strip()
    ]
    assert undocumented == []  # document the field in its class's Attributes: section


def test_defaults_are_the_dataclass_defaults(hooks, tables):
    for title, key, _, default in _expected_keys(hooks):
        row = tables[title][key]
        if key == "method":
            assert row.default == f"`{hooks.group_defaults()['method']}`"
        elif dataclasses.is_dataclass(default) and title == "Top level":
            assert row.default.startswith("see [")
        else:
            assert row.default == f"`{hooks.format_value(default)}`", key


def test_scaled_fields_say_they_carry_the_scene_scale(hooks, tables):
    for title, key, f, _ in _expected_keys(hooks):
        power = int(f.metadata.get(SCALE_KEY, 0))
        assert ("scenario.scale" in tables[title][key].unit) == bool(power), key
    assert tables["`method=dmp_ps`"]["method.beta_ps"].unit == "1/m^2, × `scenario.scale`⁻²"
    assert tables["`controller`"]["controller.margin"].unit == "m, × `scenario.scale`"


def test_units_come_from_comments_and_docstrings(tables):
    assert tables["Top level"]["outer_hz"].unit == "Hz"  # docstring: "method update rate [Hz]."
    assert tables["`method=amex`"]["method.approach_rate"].unit == "1/s"  # comment: # [1/s]
    assert tables["`mismatch`"]["mismatch.damping"].unit == "N m s/rad"


def test_the_page_links_only_to_its_own_tables(hooks):
    page = hooks.config_reference()
    ids = set(re.findall(r"\{#([a-z0-9_-]+)\}", page))
    links = set(re.findall(r"\]\(#([a-z0-9_-]+)\)", page))
    assert links and links <= ids


def test_every_config_group_option_is_listed(hooks):
    listed = {(g, o) for g, o, _ in hooks.config_groups()}
    assert ("method", "amex") in listed
    assert ("experiment", "ablation/1_harness") in listed
    assert ("hydra/launcher", "slurm") in listed
    assert all(text for _, _, text in hooks.config_groups())


def test_an_attributes_continuation_line_stays_with_its_entry(hooks):
    doc = """A node.

    Attributes:
        first: what it is, continued
        (`amex.core.scaling`).
        second: the next one
            over two lines [m].
    """
    assert hooks._attributes_section(doc) == {
        "first": "what it is, continued (`amex.core.scaling`).",
        "second": "the next one over two lines [m].",
    }
