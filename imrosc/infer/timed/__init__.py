"""Time-related invariants (thesis 3.4.1): message frequency, windowed variance, change rate;
and the window's mean.

``make_states(variables, tunables, families)`` builds the enabled states of one program
point; :mod:`imrosc.infer.timed.windows` defines exactly what a window is and how a
window's variance is computed (the live monitor must compute the same).
"""

from __future__ import annotations

from imrosc.infer.timed.families import (
    FrequencyState,
    MeanState,
    RateState,
    StepState,
    TimedState,
    VarianceState,
    make_states,
)
from imrosc.infer.timed.windows import (
    TIME_EPSILON,
    effective_width,
    window_mean,
    window_starts,
    window_variance,
    windowed_moments,
    windowed_variances,
)

__all__ = [
    "TIME_EPSILON",
    "FrequencyState",
    "MeanState",
    "RateState",
    "StepState",
    "TimedState",
    "VarianceState",
    "effective_width",
    "make_states",
    "window_mean",
    "window_starts",
    "window_variance",
    "windowed_moments",
    "windowed_variances",
]
