"""How close the authors' chain comes to itself in ``experiment=original`` (docs/original.md).

Their collision costs (the proxy task of the inner controller and CR's plan term) also summed
the chain's self-proximities: pairs of links at least 3 apart in the tree closer than the
margin (0.1 m). Ours leave them out. This runs episodes of the original experiment with a
recorder that measures, at every outer step, the distance between every two capsules of the
chain that are not neighbours (coal, the shapes of ``robot.capsules``), and prints per cell the
smallest one and how many outer steps had a pair inside the margin. A pair outside the margin
adds exactly 0 to either cost, so none inside means that including them changes no number.

Usage: ``python examples/self_proximities.py TASK METHOD [ENVIRONMENTS]`` (default 150), e.g.
``for t in 1 2 3 4; do for m in amex dmp cr; do python examples/self_proximities.py $t $m; done;
done`` (about 0.5 s per episode).
"""

import itertools
import json
import sys

import coal
import numpy as np
import pinocchio as pin

import amex
from amex.experiment.runner import prepare, setup
from amex.sim.episode import run_episode
from amex.sim.scenario import make_scenario

MARGIN = 0.1  # [m] the authors' proxy margin (controller.margin at scale 1)


class SelfProximities:
    """A recorder: the smallest distance of every non-neighbour capsule pair over an episode."""

    def __init__(self, robot, apart=2):
        self.model, self.capsules = robot.model, robot.capsules
        self.data = self.model.createData()
        self.shapes = [
            coal.Capsule(c.radius, 2 * c.half_length)
            if c.half_length > 0
            else coal.Sphere(c.radius)
            for c in self.capsules
        ]
        n = len(self.capsules)
        self.pairs = [(i, j) for i, j in itertools.combinations(range(n), 2) if j - i >= apart]
        self.closest = dict.fromkeys(self.pairs, np.inf)
        self.steps_inside = 0

    def record(self, step):
        """Measure every pair at this outer step's configuration."""
        pin.forwardKinematics(self.model, self.data, step.state.q)
        frames = []
        for c in self.capsules:
            pose = self.data.oMi[c.joint_id] * c.placement
            frames.append(coal.Transform3s(pose.rotation, pose.translation))
        inside = False
        for i, j in self.pairs:
            result = coal.DistanceResult()
            d = coal.distance(
                self.shapes[i], frames[i], self.shapes[j], frames[j], coal.DistanceRequest(), result
            )
            self.closest[i, j] = min(self.closest[i, j], d)
            inside |= d < MARGIN
        self.steps_inside += inside

    def finish(self, result):
        """Nothing to close."""
        pass


def main(task, method, environments=150):
    """Run ``environments`` episodes of the cell and print what the recorder measured."""
    config = amex.compose("experiment=original", task=task, method=method)
    context = prepare(config)
    run = setup(config, context)
    closest, episodes_inside, steps_inside = {}, 0, 0
    for env in range(environments):
        stepper = run.method(context.plan, run.params, run.outer_dt, context.robot)
        scene = make_scenario(
            run.scene, run.task, run.seed, env, context.plan.y[0, :3], context.plan.duration
        )
        recorder = SelfProximities(context.robot)
        run_episode(
            context.robot,
            stepper,
            scene,
            run.gains,
            run.loop,
            recorder,
            **run.world,
            reference_path=context.plan.y[:, :3],
        )
        for pair, d in recorder.closest.items():
            closest[pair] = min(closest.get(pair, np.inf), d)
        episodes_inside += recorder.steps_inside > 0
        steps_inside += recorder.steps_inside
    two_apart = min(closest.items(), key=lambda item: item[1])
    three_apart = min(d for (i, j), d in closest.items() if j - i >= 3)
    print(
        json.dumps(
            {
                "task": task,
                "method": method,
                "environments": environments,
                "closest_pair": list(two_apart[0]),
                "closest_distance": round(float(two_apart[1]), 4),
                "closest_3_apart": round(float(three_apart), 4),
                "episodes_within_margin": int(episodes_inside),
                "outer_steps_within_margin": int(steps_inside),
            }
        )
    )


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 150)
