"""Result codes carried from the Newton point to every result, in the manner of Optimistix.

A code is stored per point as an ``int32`` array (``HalfshaftSolution.result``,
``KinematicMetrics.result``, ``GAFResult.result``, the Hertz κ solve, sweeps and
the optimiser). Combining codes keeps the worst one: [`worst`][tripodjax.results.worst].
"""

import enum

import jax
import jax.numpy as jnp
from jax.typing import ArrayLike


class RESULTS(enum.IntEnum):
    """Outcome of a solve, per point. Larger values are worse; ``successful`` is 0."""

    successful = 0
    """The solve met its tolerance."""
    max_steps_reached = 1
    """The iteration cap was reached before the tolerance was met."""
    singular_jacobian = 2
    """The Newton Jacobian was singular (or non-finite) at an iterate."""
    nonfinite = 3
    """A NaN or an infinity appeared in the input or the answer."""
    outside_validity = 4
    """The answer lies outside the model's validity: a cheap fidelity's own error estimate is
    above its stated accuracy, a traced input lies outside its documented domain (e.g. a layout
    beyond γ0 = 45° or R/l = 0.2, which `Layout` refuses where concrete), or (the force model) a
    roller is not pressed onto its track."""

    def describe(self) -> str:
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    RESULTS.successful: "successful",
    RESULTS.max_steps_reached: "the iteration cap was reached before the tolerance was met",
    RESULTS.singular_jacobian: "the Newton Jacobian was singular",
    RESULTS.nonfinite: "a NaN or an infinity appeared in the input or the answer",
    RESULTS.outside_validity: (
        "outside the model's validity: the cheap fidelity's error estimate is above its stated "
        "accuracy, an input lies outside its domain, or a roller of the force model is not "
        "pressed onto its track (N < 0)"
    ),
}


def worst(*codes: ArrayLike, axis: int | tuple[int, ...] | None = None) -> jax.Array:
    """The worst code among ``codes`` (broadcast together); reduced over ``axis`` when given."""
    combined = codes[0]
    for code in codes[1:]:
        combined = jnp.maximum(combined, code)
    combined = jnp.asarray(combined, jnp.int32)
    return combined if axis is None else jnp.max(combined, axis=axis)


def code_where(condition: ArrayLike, code: int, otherwise: ArrayLike) -> jax.Array:
    """``code`` where ``condition`` holds, else ``otherwise`` (int32)."""
    return jnp.where(condition, jnp.int32(code), jnp.asarray(otherwise, jnp.int32))
