"""Every view takes its colours from amex.core.palette, and a method's colour means that method.

The palette's colours (every registered method's, the spares for plugins, the goal, obstacle,
reference and neutral roles) are pairwise apart (CIELAB). Then each view is rendered for a CR
episode of Task 3 (a goal, an obstacle and a plan) and the colours it actually used are read back:
``amex-log plot`` (the figure's artists), the MCAP writer's Foxglove scene (the decoded scene
messages), ``amex-log video`` (the scene's geoms of a frame) and the live page (its scene and plot
handles). A colour used for a role must be that role's; a colour near any method's must be the
episode's own method's colour or a shade of it, used for the method's own data.
"""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest

from amex.core import palette
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log import read_log
from amex.methods import METHODS, get_method

METHOD = "cr"  # the method with a plan in its internals (drawn by every view)
ROLES = ("goal", "obstacle", "reference", "neutral")


def method_colors() -> dict[str, str]:
    colors = {name: palette.method_color(name) for name in METHODS}
    colors.update({f"spare {k}": c for k, c in enumerate(palette.SPARE_COLORS)})
    return colors


def is_shade_of(color: str, method: str) -> bool:
    """``color`` is ``method``'s colour mixed with 0-70 % white."""
    base = palette.method_color(method)
    return any(palette.distance(color, palette.lighter(base, a)) < 3.0
               for a in np.linspace(0.0, 0.7, 71))  # fmt: skip


def check_uses(uses: list[tuple[str, str]], method: str, view: str) -> None:
    """Each ``(role, colour)`` of a view follows the palette's rules (module notes)."""
    assert uses, f"{view}: no colours read back"
    others = {n: c for n, c in method_colors().items() if n != method}
    for role, color in uses:
        color = color.lower()
        if role == "method":
            assert is_shade_of(color, method), f"{view}: {color} for {method} is not its colour"
            nearest = min(others, key=lambda n: palette.distance(color, others[n]))
            assert palette.distance(color, others[nearest]) > 10, (
                f"{view}: {method}'s {color} looks like {nearest}'s {others[nearest]}"
            )
            continue
        assert role in ROLES, f"{view}: a colour for {role!r}, which has none in the palette"
        assert palette.distance(color, palette.ROLE_COLORS[role]) < 1.0, (
            f"{view}: the {role} is drawn {color}, the palette says {palette.ROLE_COLORS[role]}"
        )
        for name, own in method_colors().items():
            assert palette.distance(color, own) >= palette.MIN_DISTANCE, (
                f"{view}: the {role} is drawn in {name}'s colour {own}"
            )
    assert any(role == "method" for role, _ in uses), f"{view}: the method is not drawn"


def test_palette_colours_are_pairwise_distinct():
    colors = {**{f"method {n}": c for n, c in method_colors().items()}, **palette.ROLE_COLORS}
    for (a, ca), (b, cb) in itertools.combinations(colors.items(), 2):
        if ca == cb and a.startswith("method") and b.startswith("method"):
            continue  # two plugins may share a spare colour
        assert palette.distance(ca, cb) >= palette.MIN_DISTANCE, f"{a} {ca} ~ {b} {cb}"


def test_a_plugin_keeps_one_colour_that_is_no_role_colour():
    color = palette.method_color("some_plugin")
    assert color == palette.method_color("some_plugin") and color in palette.SPARE_COLORS


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    config = RunConfig(task=3, max_time=1.0)
    config.method = get_method(METHOD).config_class()
    path = tmp_path_factory.mktemp("colors") / "cr.mcap"
    run_one(config, prepare(config), 0, path)
    return path


def test_plot_uses_the_palette(log):
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    from amex.log.plot import episode_figure

    fig = episode_figure(read_log(log))
    uses = []
    try:
        for ax in fig.axes:
            for line in ax.get_lines():
                uses.append((line.get_gid() or "undeclared", to_hex(line.get_color())))
            for collection in ax.collections:
                for rgba in collection.get_facecolor()[:1]:
                    uses.append((collection.get_gid() or "undeclared", to_hex(rgba)))
    finally:
        plt.close(fig)
    check_uses(uses, METHOD, "amex-log plot")


def _scene_colors(data, topic: str) -> list[tuple[str, str]]:
    roles = {"goal": "goal", "obstacles": "obstacle", "reference": "reference",
             "tcp_path": "method", "plan": "method"}  # fmt: skip
    uses = []
    for message in data.decoded(topic):
        for entity in message.data.get("entities", []):
            role = roles.get(entity.get("id"), "undeclared")
            for part in entity.get("lines", []) + entity.get("spheres", []):
                c = part.get("color", {})
                uses.append((role, palette.hex_color([c.get(k, 0.0) for k in "rgb"])))
    return uses


def test_foxglove_scene_uses_the_palette(log):
    data = read_log(log)
    uses = []
    for topic in ("/scene/world", "/scene/path", "/scene/plan", "/scene/reference"):
        found = _scene_colors(data, topic)
        assert found, f"nothing drawn on {topic}"
        uses += found
    check_uses(uses, METHOD, "Foxglove scene")


def test_video_frame_uses_the_palette(log):
    import mujoco

    from amex.log.render import gl_context
    from amex.log.video import _Panel, track_of

    track = track_of(read_log(log))
    gl = gl_context(160, 120)
    try:
        panel = _Panel(track, 160, 120, "visual")
        context = mujoco.MjrContext(panel.model, mujoco.mjtFontScale.mjFONTSCALE_100)
        try:
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
            panel.camera.distance = 2.0
            panel.draw(context, 0.8, mujoco.MjrRect(0, 0, 160, 120))
        finally:
            context.free()
    finally:
        gl.free()
    kinds = {int(mujoco.mjtGeom.mjGEOM_LINE), int(mujoco.mjtGeom.mjGEOM_SPHERE)}
    drawn = [panel.scene.geoms[i] for i in range(panel.scene.ngeom)]
    colors = {palette.hex_color(g.rgba) for g in drawn if int(g.type) in kinds}
    roles = {palette.GOAL_COLOR: "goal", palette.OBSTACLE_COLOR: "obstacle",
             palette.REFERENCE_COLOR: "reference"}  # fmt: skip
    uses = [(roles.get(c, "method"), c) for c in colors]
    check_uses(uses, METHOD, "amex-log video")
    assert {"goal", "obstacle", "reference", "method"} <= {role for role, _ in uses}


def test_live_page_uses_the_palette(tmp_path):
    import viser

    from amex.app.live.page import LivePage
    from amex.app.live.session import LiveSession

    session = LiveSession(["task=3", f"method={METHOD}"], record_dir=tmp_path)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        page = LivePage(server, session)
        session.start()
        end = time.monotonic() + 60
        while session.state.t < 0.5 and time.monotonic() < end:
            time.sleep(0.05)
        for _ in range(5):  # one slow frame: paths and plan
            page.update(session.state)
        assert page._path_line.visible  # the executed path is drawn, in its colour
        check_uses(page.colors(), METHOD, "live page")
        assert {"goal", "obstacle", "reference"} <= {role for role, _ in page.colors()}
    finally:
        session.close()
        server.stop()
