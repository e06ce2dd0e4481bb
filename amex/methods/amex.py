"""Adaptive Motion Execution (AMEX): the paper's Algorithm 1 with Eq. 7, 8 and 9.

The reference samples are reparametrized over the phase s in [0, 1] as a quadratic B-spline
``tau_ref(s)``; the current plan is ``tau_plan(s~) = tau_ref(s~) + p + (s~ - 1) q``
(:class:`~amex.plan.spline.WarpedSpline`), ``Delta s_ref = dt / T_ref``. Each outer step, with the
measured task state y and goal g (Algorithm 1, steps 2-4):

* Eq. 8, phase: ``s += Delta s_ref * clip(delta_g * delta_y, rate_min, rate_max)`` with
  ``delta_g = ||g_ref - tau_ref(s_t,prev)|| / ||g - y||`` and
  ``delta_y = ||y - y_prev|| / ||y*_prev - y_prev||``; the first ``warmup_steps`` updates add
  Delta s_ref.
* Eq. 7, plan: ``tau_plan += Delta g + (Delta g - Delta y)(s~ - 1) / (1 - s)`` with
  ``Delta y = y - tau_plan(s)`` and ``Delta g = g - tau_plan(1)``, so that ``tau_plan(s) = y`` and
  ``tau_plan(1) = g``.
* Eq. 9, target: ``y* = y + ||tau_ref(s_t) - tau_ref(s)|| d``, d the unit direction of the plan
  over the step (``eq9="secant"``) or its tangent at s (``"tangent"``), and
  ``y_dot* = (y* - y) / dt``; once s reaches 1, a first-order approach to g.

The phase convention, the guards (zero divisors, bounded phase step, no overshoot, the end of the
phase) and the measurements behind them are in ``docs/methods/amex.md``. The step is O(m),
independent of the number of spline control points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from amex.core.compiled import kernel
from amex.core.types import PD, Command, Observation, require_finite
from amex.methods.amex_layout import STATE_FIELDS
from amex.methods.base import Method, MethodConfig, invalid
from amex.plan.spline import QuadraticBSpline, WarpedSpline, max_sample_error

if TYPE_CHECKING:  # no simulator stack needed to use a method
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

EQ9_FORMS = ("secant", "tangent")


@dataclass
class AMEXConfig(MethodConfig):
    """AMEX settings; inner gains are the original code's.

    Attributes:
        pos: inner PD on the TCP position target (original: Kp 1, Kd 100).
        dir: inner PD on the TCP axis target (original: Kp 1, Kd 100).
        n_control: spline control points; 0: one per reference sample (interpolation).
        warmup_steps: updates that advance the phase by exactly Delta s_ref (original: 2).
        rate_min: lower bound of the phase factor delta_g * delta_y (>= 0: s never decreases).
        rate_max: upper bound of the phase factor (the phase step is at most rate_max Delta s_ref).
        eps_goal: distance to the goal below which the robot counts as at the goal.
        eps_step: commanded step below which delta_y is taken as 1.
        eps_tangent: plan tangent norm below which d points at the goal.
        end_margin: phase distance to 1 at which the final approach begins.
        end_fraction: the final approach also begins once the reference's remaining distance
            ``||g_ref - tau_ref(s_t)||`` is below this fraction of its start-goal distance.
        approach_rate: gain of the final approach.
        eq9: ``"secant"`` (one reference step; exact on an executed plan) or ``"tangent"`` (the
            derivatives at s, as the paper writes Eq. 9); see the module notes.
    """

    name: str = "amex"
    pos: PD = field(default_factory=lambda: PD(1.0, 100.0, 1.0))
    dir: PD = field(default_factory=lambda: PD(1.0, 100.0, 0.5))
    n_control: int = 0  # [-]
    warmup_steps: int = 2  # [steps]
    rate_min: float = 0.0  # [-]
    rate_max: float = 5.0  # [-] (goals of Task 1 need 0.6-2.4)
    eps_goal: float = 1e-9  # [task units: m, axis -]
    eps_step: float = 1e-9  # [task units]
    eps_tangent: float = 1e-12  # [task units per unit phase]
    end_margin: float = 1e-6  # [-] phase; bounds 1 / (1 - s) in Eq. 7 by 1e6
    end_fraction: float = 1e-4  # [-] of ||g_ref - tau_ref(0)|| (benchmark: ~24 um); 0: off
    approach_rate: float = 5.0  # [1/s]
    eq9: str = "secant"

    def validate(self) -> None:
        """Raise :class:`ConfigError` for settings AMEX cannot run with (whatever the plan)."""
        if not (self.n_control == 0 or self.n_control >= 3):
            raise invalid("n_control", self.n_control, "0 or 3..N + 1 (the reference samples)")
        if not (int(self.warmup_steps) == self.warmup_steps and self.warmup_steps >= 0):
            raise invalid("warmup_steps", self.warmup_steps, "an integer >= 0")
        if not 0.0 <= self.rate_min <= self.rate_max or not self.rate_max > 0.0:
            raise invalid(
                "rate_min, rate_max", (self.rate_min, self.rate_max), "0 <= min <= max, max > 0"
            )
        for key in ("eps_goal", "eps_step", "eps_tangent", "approach_rate", "end_fraction"):
            if not getattr(self, key) >= 0.0:
                raise invalid(key, getattr(self, key), ">= 0")
        if self.eq9 not in EQ9_FORMS:
            raise invalid("eq9", self.eq9, EQ9_FORMS)
        if not 0.0 < self.end_margin < 1.0:
            raise invalid("end_margin", self.end_margin, "in (0, 1)")


class AMEXTarget(NamedTuple):
    """AMEX's output of one update (target fields named as :class:`~amex.methods.dmp.DMPTarget`'s).

    Attributes:
        y_star: next task-space target y*, shape (m,).
        yd_star: velocity target y_dot*, shape (m,) [task units / s].
        s: phase after the update, in [0, 1].
        delta_g: Eq. 8 goal factor (guarded), [-].
        delta_y: Eq. 8 execution factor (guarded), [-].
    """

    y_star: np.ndarray
    yd_star: np.ndarray
    s: float
    delta_g: float
    delta_y: float


class AMEX(Method):
    """Adaptive Motion Execution (the paper's Algorithm 1; see the module notes).

    Args:
        plan: the reference; its task path ``plan.y`` (N + 1 samples of tau_hat_ref over T_ref,
            shape (N + 1, m)) is used, e.g. ``ReferencePlan.from_path(y, duration)``.
        config: :class:`AMEXConfig` (None: the defaults).
        dt: outer (control) period [s]; Delta s_ref = dt / T_ref.
        robot: not used.

    Attributes:
        reference: tau_ref over the phase, a quadratic B-spline.
        plan: tau_plan, the reference plus the affine offset of Eq. 7 (valid while s < 1).
        fit_error: largest deviation of ``reference`` from the samples [task units].
        ds_ref: Delta s_ref [-].
        peak_speed: largest reference speed ``max ||tau_ref'(s)|| / T_ref`` [task units / s].
    """

    name = "amex"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = AMEXConfig

    needs_motion = True  # Eq. 8 measures progress as the reference's remaining distance
    config: AMEXConfig

    def __init__(
        self,
        plan: ReferencePlan,
        config: AMEXConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        p = self.config
        Y = np.array(plan.y, dtype=float)
        if not p.n_control <= len(Y):
            raise invalid("n_control", p.n_control, f"0 or 3..{len(Y)} (the reference samples)")

        self.reference = QuadraticBSpline.fit(Y, p.n_control or None)
        self.fit_error = max_sample_error(self.reference, Y)
        self.plan = WarpedSpline(self.reference)
        self.duration = float(plan.duration)
        self.ds_ref = self.dt / self.duration
        self.g_ref = self.reference.control_points[-1].copy()  # tau_ref(1)
        fine = np.linspace(0.0, 1.0, 4 * len(Y) + 1)
        speeds = np.linalg.norm(self.reference.derivative(fine), axis=1) / self.duration
        self.peak_speed = float(speeds.max())
        self.warmup_steps = int(p.warmup_steps)
        self.rate_min, self.rate_max = float(p.rate_min), float(p.rate_max)
        self.eps_goal, self.eps_step = float(p.eps_goal), float(p.eps_step)
        self.eps_tangent = float(p.eps_tangent)
        self.end_margin = float(p.end_margin)
        self.end_distance = float(p.end_fraction) * float(np.linalg.norm(Y[-1] - Y[0]))
        self.approach_rate = float(p.approach_rate)
        self.secant = p.eq9 == "secant"

        m = Y.shape[1]
        # One matmul per step evaluates tau_ref(s_t), tau_ref(s), tau_ref'(s): a weight window
        # wide enough for both spans (s_t - s <= Delta s_ref), on zero-padded control points.
        width = 3 + self.reference.max_index_shift(self.ds_ref) + 1
        self._C = np.vstack([self.reference.control_points, np.zeros((width - 3, m))])
        self._W = np.zeros((3, width))  # rows: values at s_t, values at s, derivatives at s
        self._W_t = self._W[0]
        self._X = np.empty((4, m))  # g_ref, tau_ref(s_t), tau_ref(s), tau_ref'(s)
        self._X[0] = self.g_ref
        self._X_eval = self._X[1:]
        self._D = np.empty((2, m))  # g_ref - tau_ref(s_t), tau_ref(s_t) - tau_ref(s)
        # the execution's state, shared by the compiled update and the numpy oracle:
        # the plan's offset p and slope q and the previous y as rows of one array, the scalars
        # (amex_layout.STATE_FIELDS) in another
        self._vectors = np.zeros((3, m))
        self.plan.p, self.plan.q, self._y_prev = self._vectors
        self._state = np.zeros(len(STATE_FIELDS))
        self._consts = np.array(
            [
                self.ds_ref,
                self.warmup_steps,
                self.rate_min,
                self.rate_max,
                self.eps_goal,
                self.eps_step,
                self.eps_tangent,
                self.end_margin,
                self.end_distance,
                self.approach_rate,
                self.peak_speed,
                self.dt,
                float(self.secant),
                self.reference.n_control,
                *self.g_ref,
            ]
        )
        self._knots = np.ascontiguousarray(self.reference.knots, dtype=np.float64)
        self._m = m
        self._kernel = kernel("amex.methods.amex_kernels", "amex_update")
        self.restart()

    # ----------------------------------------------------------------------------- numpy API
    def restart(self) -> None:
        """Start a new execution: s = 0, tau_plan = tau_ref (Algorithm 1, initialization)."""
        self.plan.reset()
        st = self._state
        st[:] = 0.0  # s, updates so far, final approach, ||y*_prev - y_prev||, aimed phase, ...
        r = self.g_ref - self.reference.control_points[0]
        st[5] = math.sqrt(np.dot(r, r))  # ||g_ref - tau_ref(s)||
        self._outputs: tuple[np.ndarray, np.ndarray] | None = None  # the last y*, y_dot*

    @property
    def s(self) -> float:
        """The phase, in [0, 1]."""
        return float(self._state[0])

    @property
    def final_approach(self) -> bool:
        """Whether the phase reached 1 and the final approach to g runs."""
        return bool(self._state[2])

    def _advance(self, y: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The compiled update (:func:`amex.methods.amex_kernels.amex_update`): y*, y_dot*."""
        y = np.ascontiguousarray(y, dtype=np.float64)
        g = np.ascontiguousarray(g, dtype=np.float64)
        m = self._m
        y_star, yd_star = np.empty(m), np.empty(m)
        if self._kernel(
            y, g, y_star, yd_star, self._state, self._vectors, self._C, self._knots, self._consts
        ):
            require_finite(y=y, g=g)  # raises, naming the bad input
        self._outputs = y_star, yd_star
        return y_star, yd_star

    def _target(self) -> AMEXTarget | None:
        """The last update's :class:`AMEXTarget` (None before the first)."""
        if self._outputs is None:
            return None
        st = self._state
        return AMEXTarget(*self._outputs, float(st[8]), float(st[6]), float(st[7]))

    def update(self, y: np.ndarray, g: np.ndarray) -> AMEXTarget:
        """One outer step of Algorithm 1 (steps 2-4) for task state y and goal g, shapes (m,).

        Compiled (:mod:`amex.methods.amex_kernels`); :meth:`update_reference` is the same in
        numpy, operation for operation.

        Raises:
            InputError: y or g holds a NaN or an infinity; AMEX is left as it was.
        """
        self._advance(y, g)
        return self._target()  # type: ignore[return-value]

    def update_reference(self, y: np.ndarray, g: np.ndarray) -> AMEXTarget:
        """:meth:`update` in numpy (the test oracle of the compiled update).

        Raises:
            InputError: y or g holds a NaN or an infinity; AMEX is left as it was.
        """
        require_finite(y=y, g=g)
        st = self._state
        self._s, self._k, self._final = float(st[0]), int(st[1]), bool(st[2])
        self._step_prev, self._aimed, self._ref_remaining = float(st[3]), float(st[4]), float(st[5])
        target = self._update_numpy(y, g)
        st[0], st[1], st[2] = self._s, self._k, float(self._final)
        st[3], st[4], st[5] = self._step_prev, self._aimed, self._ref_remaining
        st[6], st[7], st[8] = target.delta_g, target.delta_y, target.s
        self._outputs = target.y_star, target.yd_star
        return target

    def _update_numpy(self, y: np.ndarray, g: np.ndarray) -> AMEXTarget:
        """The body of :meth:`update_reference`, on the scalars as attributes."""
        # Eq. 8 factors, guarded; computed every step for the log, used after the warm-up.
        gy = g - y
        dist_goal = math.sqrt(np.dot(gy, gy))
        delta_g = self._ref_remaining / dist_goal if dist_goal > self.eps_goal else self.rate_max
        if self._step_prev > self.eps_step:
            d = y - self._y_prev
            delta_y = math.sqrt(np.dot(d, d)) / self._step_prev
        else:
            delta_y = 1.0
        k = self._k
        self._k = k + 1
        self._y_prev[:] = y
        if k == 0:
            s = 0.0
        elif self._final or self._aimed >= 1.0:
            s = 1.0
        else:
            rate = 1.0 if k <= self.warmup_steps else delta_g * delta_y
            s = self._s + self.ds_ref * min(max(rate, self.rate_min), self.rate_max)
        if s >= 1.0 - self.end_margin:
            return self._approach(y, gy, delta_g, delta_y)

        self._s = s
        s_t = self._aimed = min(s + self.ds_ref, 1.0)  # the phase this step's command aims at
        W, X, D = self._W, self._X, self._D
        i, W[1, 0], W[1, 1], W[1, 2], W[2, 0], W[2, 1], W[2, 2] = self.reference.weights(s)
        j, b0, b1, b2, _, _, _ = self.reference.weights(s_t)
        o = j - i
        self._W_t.fill(0.0)
        W[0, o], W[0, o + 1], W[0, o + 2] = b0, b1, b2
        np.matmul(W, self._C[i : i + W.shape[1]], out=self._X_eval)
        np.subtract(X[0:2], X[1:3], out=D)
        # Eq. 7 in closed form (WarpedSpline.anchor): tau_plan = tau_ref + p + (s~ - 1) q with
        # tau_plan(1) = g and tau_plan(s) = y.
        q = self.plan.q
        np.subtract(g, self.g_ref, out=self.plan.p)
        np.add(gy, X[2], out=q)
        q -= X[0]
        q *= 1.0 / (1.0 - s)
        r_t = D[0]
        self._ref_remaining = math.sqrt(np.dot(r_t, r_t))  # delta_g's numerator, next step
        if self._ref_remaining <= self.end_distance:  # the reference has arrived: end the phase
            self._aimed = 1.0
        # Eq. 9: along the warped plan, with the reference's progress (see the module notes).
        if self.secant:
            ref_step = D[1]  # tau_ref(s_t) - tau_ref(s)
            length = math.sqrt(np.dot(ref_step, ref_step))
            direction = (s_t - s) * q  # tau_plan(s_t) - tau_plan(s)
            direction += ref_step
        else:
            tangent = X[3]
            length = self.ds_ref * math.sqrt(np.dot(tangent, tangent))  # ds ||tau_ref'(s)||
            direction = tangent + q  # tau_plan'(s)
        norm_dir = math.sqrt(np.dot(direction, direction))
        if not norm_dir > self.eps_tangent:
            if dist_goal > self.eps_goal:
                direction, norm_dir = gy, dist_goal
            else:
                length, norm_dir = 0.0, 1.0
        if length > dist_goal:  # never past the goal
            length = dist_goal
        self._step_prev = length
        step = direction * (length / norm_dir)
        return AMEXTarget(y + step, step * (1.0 / self.dt), s, delta_g, delta_y)

    def _approach(
        self, y: np.ndarray, gy: np.ndarray, delta_g: float, delta_y: float
    ) -> AMEXTarget:
        """Command the final approach at s = 1 (see the module notes)."""
        self._s = 1.0
        self._final = True
        v = self.approach_rate * gy
        speed = math.sqrt(np.dot(v, v))
        if speed > self.peak_speed:
            v *= self.peak_speed / speed
            speed = self.peak_speed
        self._step_prev = speed * self.dt
        return AMEXTarget(y + self.dt * v, v, 1.0, delta_g, delta_y)

    # ----------------------------------------------------------------------------- Method
    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: :meth:`restart` (the first update reads y_0, g_0)."""
        self.restart()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: :meth:`update` with the measured ``obs.y`` and ``obs.goal``."""
        y_star, yd_star = self._advance(obs.y, obs.goal)
        return Command.task(y_star, yd_star)

    def internals(self) -> dict[str, Any]:
        """Phase s, Eq. 8 factors delta_g and delta_y, targets y_star and yd_star (last update).

        :func:`target_internals` of :meth:`_target`, read straight from the state (a recorder
        asks at every outer step: 0.6 against 2 us).
        """
        st, outputs = self._state, self._outputs
        if outputs is None:
            return target_internals(None, st.item(0))
        return {"s": st.item(8), "delta_g": st.item(6), "delta_y": st.item(7),
                "y_star": outputs[0], "yd_star": outputs[1]}  # fmt: skip


def target_internals(last: AMEXTarget | None, s: float) -> dict[str, Any]:
    """The log record of an AMEX update (``s`` before the first one)."""
    if last is None:
        return {"s": s, "delta_g": 1.0, "delta_y": 1.0, "y_star": None, "yd_star": None}
    return {"s": last.s, "delta_g": last.delta_g, "delta_y": last.delta_y,
            "y_star": last.y_star, "yd_star": last.yd_star}  # fmt: skip
