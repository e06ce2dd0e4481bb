"""The layout of the state and constants of AMEX's compiled update (Eq. 7-9).

Apart from the compiled code (:func:`amex.methods.amex_kernels.amex_update`), so that
:class:`amex.methods.amex.AMEX` sizes and reads its arrays without importing Numba
(:mod:`amex.core.compiled`).
"""

from __future__ import annotations

#: The scalar state of an AMEX execution (:func:`amex_update`'s ``state``), by index.
STATE_FIELDS = (
    "s",  # the phase
    "k",  # updates so far
    "final",  # 1 once the final approach runs
    "step_prev",  # ||y*_prev - y_prev||; 0: no command yet
    "aimed",  # the phase the last command aimed at
    "ref_remaining",  # ||g_ref - tau_ref(s_t,prev)||, Eq. 8's delta_g numerator
    "delta_g",  # the last update's Eq. 8 factors
    "delta_y",
    "s_out",  # the last update's phase
)
#: The constants (:func:`amex_update`'s ``consts``), by index; g_ref follows them.
CONSTANTS = (
    "ds_ref",
    "warmup_steps",
    "rate_min",
    "rate_max",
    "eps_goal",
    "eps_step",
    "eps_tangent",
    "end_margin",
    "end_distance",
    "approach_rate",
    "peak_speed",
    "dt",
    "secant",
    "n_basis",  # control points of tau_ref
)
N_CONSTANTS = len(CONSTANTS)
