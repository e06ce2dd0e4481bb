"""The logs' own protobuf encoders against the SDK's objects (the oracle): the same bytes."""

import foxglove
import numpy as np
import pytest
from foxglove.messages import JointState, JointStates, Point3, SceneEntity, SceneUpdate

from amex.log import messages as M
from amex.log import scene_wire as W
from amex.log.frames import LinkTransforms, sim_stamp
from amex.log.scene import SceneChannels
from amex.log.wire import encode_step, step_encoding


def _times(rng):
    return [0.0, 1e-9, 0.01, 1.0, 3.62, 12345.678, *rng.uniform(0, 60, 20).tolist()]


def test_step_encoding_gives_the_sdks_bytes_of_tf_and_joint_states(robot):
    rng = np.random.default_rng(0)
    links = LinkTransforms(robot)
    names = list(robot.joint_names)
    encoding = step_encoding(links.constant_parts(), names)
    out = np.empty(encoding.size, dtype=np.uint8)
    times = _times(rng)
    for trial in range(400):
        q, v, qacc, tau = rng.uniform(-3.2, 3.2, (4, robot.nv))
        if trial % 3 == 0:  # exact zeros: rotation components and proto3 defaults
            q[rng.random(robot.nv) < 0.5] = 0.0
        if trial % 5 == 0:
            q[rng.random(robot.nv) < 0.5] = -0.0
            tau[:] = 0.0
        if trial % 7 == 0:
            v[0], qacc[1] = np.nan, np.inf
        t = times[trial % len(times)]
        stamp, ns = sim_stamp(t), round(t * 1e9)
        tf_sdk = links.message(q, stamp).encode()
        joints = [
            JointState(name=n, position=a, velocity=b, acceleration=c, effort=d)
            for n, a, b, c, d in zip(
                names, q.tolist(), v.tolist(), qacc.tolist(), tau.tolist(), strict=True
            )
        ]
        js_sdk = JointStates(timestamp=stamp, joints=joints).encode()
        a, b = encode_step(ns, q, v, qacc, tau, *encoding[:4], out)
        assert out[:a].tobytes() == tf_sdk
        assert out[a:b].tobytes() == js_sdk


def test_the_start_pose_has_zero_rotation_components_left_out_as_the_sdk_does(robot):
    links = LinkTransforms(robot)
    encoding = step_encoding(links.constant_parts(), list(robot.joint_names))
    q = np.zeros(robot.nv)
    out = np.empty(encoding.size, dtype=np.uint8)
    a, _ = encode_step(0, q, q, q, q, *encoding[:4], out)
    assert out[:a].tobytes() == links.message(q, sim_stamp(0.0)).encode()
    nonzero = encode_step(0, q + 0.3, q, q, q, *encoding[:4], out)[0]
    assert nonzero > a  # the zeros were really left out


@pytest.mark.parametrize("entity,thickness", [("plan", 3.0), ("reference", 2.0)])
def test_line_updates_equal_the_sdks(entity, thickness):
    rng = np.random.default_rng(1)
    encoding = W.line_encoding(entity, M.plan_color("amex"), thickness)
    for k, t in zip((1, 2, 7, 100, 401), _times(rng), strict=False):
        xyz = rng.normal(size=(k, 3))
        xyz[rng.random((k, 3)) < 0.2] = 0.0
        if k > 1:
            xyz[1] = -0.0
        ns = round(t * 1e9)
        sdk = M.line_update(sim_stamp(t), entity, M.points(xyz, k), M.plan_color("amex"), thickness)
        assert W.line_update(encoding, ns, W.line_points(xyz)) == sdk.encode()


def test_a_point_field_is_the_points_of_a_line_of_one_point():
    rng = np.random.default_rng(3)
    specials = [0.0, -0.0, np.nan, np.inf, -np.inf, 1e-300, -2.5]
    rows = [rng.choice(specials, 3) for _ in range(200)] + list(rng.normal(size=(50, 3)))
    for x, y, z in rows:
        assert W.point_field(x, y, z) == W.line_points(np.array([[x, y, z]])), (x, y, z)


def test_the_executed_path_is_the_line_of_its_points_so_far():
    scene = _scene([0.05])
    assert scene.path_update(0.0) is None
    rng = np.random.default_rng(4)
    xyz = rng.normal(size=(30, 3))
    xyz[3, 1] = 0.0
    for k, (x, y, z) in enumerate(xyz.tolist(), start=1):
        scene.add_path_point(x, y, z)
        if k in (1, 4, 30):
            expected = W.line_update(scene._path_line, 10**9 * k, W.line_points(xyz[:k]))
            assert scene.path_update(float(k)) == expected


def _world_sdk(t, goal, obstacles, radii):
    """``/scene/world``'s message built as the SDK's objects (the oracle)."""
    stamp = sim_stamp(t)
    entities = [
        SceneEntity(
            timestamp=stamp,
            frame_id="world",
            id="goal",
            spheres=[M.sphere(goal, 0.06, M.GOAL_COLOR), M.sphere(goal, 0.01, M.GOAL_DOT_COLOR)],
        )
    ]
    if len(radii):
        pairs = zip(obstacles, radii, strict=True)
        spheres = [M.sphere(c, 2 * r, M.OBSTACLE_COLOR) for c, r in pairs]
        entities.append(
            SceneEntity(timestamp=stamp, frame_id="world", id="obstacles", spheres=spheres)
        )
    return SceneUpdate(entities=entities).encode()


def _scene(radii, *, move=True):
    return SceneChannels(
        foxglove.Context(), np.zeros((2, 3)), np.asarray(radii, dtype=float),
        obstacles_move=move, method="amex", max_line_points=100,
    )  # fmt: skip


@pytest.mark.parametrize("radii", [[0.02, 0.05], [0.1], []])
def test_sphere_updates_equal_the_sdks(radii):
    rng = np.random.default_rng(2)
    times = sorted(_times(rng))
    k = len(times)
    goals = rng.normal(size=(k, 3))
    goals[rng.random((k, 3)) < 0.3] = 0.0
    goals[2] = -0.0
    obstacles = rng.normal(size=(k, len(radii), 3)) * 300  # centres of up to 2-byte lengths
    obstacles[rng.random(obstacles.shape) < 0.2] = 0.0
    goals[5, 1] = np.nan
    scene = _scene(radii)
    stamps = [round(t * 1e9) for t in times]
    updates = scene.world_updates(times, stamps, goals, list(obstacles))
    assert sorted(updates) == list(range(k))  # every step moved (or held a NaN)
    for i, t in enumerate(times):
        assert updates[i] == _world_sdk(t, goals[i].tolist(), obstacles[i].tolist(), radii)


def test_a_world_update_is_due_when_the_goal_or_an_obstacle_moved_a_millimetre_or_each_second():
    goal, obstacle = np.array([0.5, 0.1, 0.3]), np.array([[0.2, 0.0, 0.4]])
    x = np.array([1.0, 0.0, 0.0])
    times = [0.0, 0.01, 0.02, 0.03, 0.04, 1.02, 1.04, 1.05]
    goals = [goal, goal + 4e-4 * x, goal + 9e-4 * x, *[goal + 1.5e-3 * x] * 5]
    moved = [obstacle] * 7 + [obstacle + 2e-3 * x]
    stamps = [round(t * 1e9) for t in times]
    due = list(_scene([0.05]).world_updates(times, stamps, goals, moved))
    # 0.01, 0.02: 0.4 and 0.9 mm since 0.00; 0.03: 1.5 mm; 1.04: a second since 0.03; 1.05:
    # the obstacle moved 2 mm
    assert due == [0, 3, 6, 7]
    still = _scene([0.05], move=False)  # obstacles that do not move do not count
    assert list(still.world_updates(times, stamps, goals, moved)) == [0, 3, 6]
    split = _scene([0.05])  # a batch at a time: the same steps
    first = split.world_updates(times[:3], stamps[:3], goals[:3], moved[:3])
    rest = split.world_updates(times[3:], stamps[3:], goals[3:], moved[3:])
    assert [*first, *(3 + i for i in rest)] == due


def test_varints_and_timestamps_match_the_sdk():
    for value in (0, 1, 127, 128, 300, 2**31, 2**40 + 5):
        encoded = W.varint(value)
        decoded = sum((b & 0x7F) << (7 * i) for i, b in enumerate(encoded))
        assert decoded == value and all(b & 0x80 for b in encoded[:-1])
    for t in (0.0, 1.0, 0.5, 1e-9, 7.000000001):
        ns = round(t * 1e9)
        empty = SceneUpdate(entities=[SceneEntity(timestamp=sim_stamp(t))]).encode()
        assert W.timestamp_field(ns) == empty[2:]  # after the entities tag and length


def test_points_of_a_line_keep_every_row_when_there_are_few():
    xyz = np.arange(12.0).reshape(4, 3)
    assert M.point_rows(4, 100) is None
    expected = [Point3(x=x, y=y, z=z).encode() for x, y, z in xyz.tolist()]
    assert [p.encode() for p in M.points(xyz, 100)] == expected
    assert M.point_rows(401, 100).tolist()[-1] == 400


def test_drawn_rows_are_distinct_increasing_and_those_np_unique_kept():
    for k in range(101, 2000, 7):
        rows = M.point_rows(k, 100)
        expected = np.unique(np.linspace(0, k - 1, 100).round().astype(int))
        assert np.array_equal(rows, expected) and rows[0] == 0 and rows[-1] == k - 1


def test_a_batchs_plans_of_one_group_are_drawn_as_each_alone(robot):
    from amex.core.lazy import Lazy, LazyRows
    from amex.plan.batch_kinematics import BatchKinematics

    kinematics = BatchKinematics(robot)
    positions, tcp = kinematics.frame_positions, robot.tcp_frame_id
    rng = np.random.default_rng(6)

    def knots(k):
        return rng.uniform(-2.5, 2.5, (k, robot.nv))

    def cr_plan(q):  # as CR's internals() makes it: a new lambda, the same group
        return LazyRows.rowwise(lambda a: positions(a, tcp), q, (positions, tcp))

    plans = [cr_plan(knots(k)) for k in (1, 40, 100, 101, 250, 401)]
    plans += [None, np.zeros((3, 2)), rng.normal(size=(150, 3)), Lazy(lambda: np.ones((5, 3)))]
    plans += [LazyRows.rowwise(lambda a: a[:, :3] * 2.0, rng.normal(size=(120, 4)))]  # no group
    plans += [cr_plan(knots(300)), cr_plan(knots(0))]
    flat = (len, 2)  # a group whose map gives no (k, >= 3) points: nothing drawn
    plans += [LazyRows.rowwise(lambda a: a[:, :2], rng.normal(size=(k, 3)), flat) for k in (4, 9)]
    times = [0.05 * j for j in range(len(plans))]
    scene = _scene([0.05])
    alone = [scene.plan_update(t, plan) for t, plan in zip(times, plans, strict=True)]
    assert scene.plan_updates(times, plans) == alone
    assert sum(update is None for update in alone) == 4  # None, the (3, 2) array, the flat ones


def test_a_batchs_lines_are_each_line_alone():
    rng = np.random.default_rng(8)
    encoding = W.line_encoding("plan", M.plan_color("cr"), 3.0)
    sizes = [0, 1, 5, 100, 0, 37]
    points = rng.normal(size=(sum(sizes), 4))  # a fourth column is not drawn
    points[2] = [0.0, -0.0, np.nan, 1.0]
    points[3] = [np.inf, 0.0, -np.inf, 0.0]
    points[10:20, 1] = 0.0
    ends = np.cumsum(sizes).tolist()
    stamps = [0, 1, 999_999_999, 1_000_000_000, 12_345_678_901, 2**40]
    lines = W.line_updates(encoding, stamps, points, ends)
    starts = [0, *ends[:-1]]
    for line, ns, a, b in zip(lines, stamps, starts, ends, strict=True):
        assert line == W.line_update(encoding, ns, W.line_points(points[a:b]))


def test_a_cr_log_writes_each_steps_topics_in_order_and_the_plan_at_its_drawn_knots(tmp_path):
    """The batch writes every message of a step before the next step's, in the logger's order,
    and CR's plan (a LazyRows) is drawn at the knots' TCP positions, computed for those alone."""
    from mcap.reader import make_reader

    from amex.core.lazy import LazyRows
    from amex.experiment.config import RunConfig
    from amex.experiment.runner import _scenario, prepare, run_setup_with, setup
    from amex.log import EpisodeLogger
    from amex.log.scene import SceneChannels
    from amex.methods import METHODS

    config = RunConfig(task=1, max_time=1.2)
    config.method = METHODS["cr"].config_class()
    run = setup(config, prepare(config))
    drawn = []  # what the scene drew: the plan's length, the rows asked for, the points
    plan_updates = SceneChannels.plan_updates

    def spy(self, times, plans):
        for plan in plans:
            assert isinstance(plan, LazyRows)  # not computed at the step: at the batch
            rows = self._rows(plan.length)
            whole = plan.take(None)
            drawn.append(whole if rows is None else whole[rows])
        return plan_updates(self, times, plans)

    SceneChannels.plan_updates = spy
    try:
        path, context = tmp_path / "cr.mcap", run.context
        scenario = _scenario(run, 0)
        with EpisodeLogger(path, context.robot, context.plan, scenario, {}) as logger:
            run_setup_with(run, 0, logger)
    finally:
        SceneChannels.plan_updates = plan_updates
    order = ["/tf", "/joint_states", "/tcp", "/goal", "/command", "/method", "/scene/world",
             "/scene/path", "/scene/plan", "/scene/reference"]  # fmt: skip
    with open(path, "rb") as f:
        messages = [(m.log_time, c.topic, m.data) for _, c, m in make_reader(f).iter_messages(
            log_time_order=False)]  # fmt: skip
    steps = [m for m in messages if m[1] not in ("/reference", "/episode")]
    times = [t for t, _, _ in steps]
    assert times == sorted(times)  # the file's order is the steps' order
    for t in sorted(set(times))[1:-1]:  # every step but the header's and the end's
        topics = [topic for u, topic, _ in steps if u == t]
        assert topics[:6] == order[:6] and topics == sorted(topics, key=order.index), topics
    plans = [data for _, topic, data in steps if topic == "/scene/plan"]
    assert len(plans) == len(drawn) > 10
    for data, points in zip(plans, drawn, strict=True):
        assert W.line_points(points) in data  # the same doubles as the whole plan's rows
