"""The weights of the trajectory cost's terms, declared once (f(x) in docs/planner.md).

The reference plan's settings (:class:`~amex.plan.reference.PlanConfig`) inherit
:class:`CostWeights`, CR's (:class:`~amex.methods.cr.CRConfig`) :class:`CollisionWeights`, and
:meth:`TrajectoryCosts.from_weights <amex.plan.problem.TrajectoryCosts.from_weights>` turns
either into the solver's costs. Defaults are the original's values.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class CostWeights:
    """Weights of the acceleration and final terms.

    Attributes:
        acceleration: weight of ``sum_t q_ddot_t^T H q_ddot_t dt``.
        final_position: weight of the squared TCP position error at q_T.
        final_velocity: weight of the squared final velocity (joint, or TCP for the original).
        final_axis: weight of the squared TCP z-axis error at q_T.
        final_axis_velocity: weight of the squared TCP z-axis rate at the end.
    """

    acceleration: float = 1.0  # [s^3/rad^2 per unit cost]
    final_position: float = 1e4  # [1/m^2] original
    final_velocity: float = 1e3  # [s^2/rad^2] original
    final_axis: float = 1e4  # [-] original
    final_axis_velocity: float = 1e3  # [s^2] original


@dataclass
class CollisionWeights(CostWeights):
    """:class:`CostWeights` plus the collision proxy ``max(0, 1 - d / margin)^2`` per knot and pair.

    Attributes:
        collision: weight of the collision term.
        collision_margin: distance below which the collision term acts [m].
    """

    collision: float = 1.0  # [-] original
    collision_margin: float = 0.02  # [m] the original's 0.1 m at the Panda's scale 0.2
