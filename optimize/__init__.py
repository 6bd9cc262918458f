"""The joint-design problem and its optimiser (``optimize-joint``), as ``tripodjax.optimize``.

- [`load_spec`][tripodjax.optimize.load_spec] — the design specification (TOML, checked; an
  embedded default), a pytree whose numbers are traced and whose structure is static.
- [`evaluate`][tripodjax.optimize.evaluate] — objective, margins and quantities of one design.
- [`solve`][tripodjax.optimize.solve] — the proposed design, by an augmented Lagrangian on
  optax's L-BFGS; compiled once per spec structure.
- [`solve_family`][tripodjax.optimize.solve_family],
  [`pareto_front`][tripodjax.optimize.pareto_front] — many scenarios in one batch.
- [`sensitivities`][tripodjax.optimize.sensitivities] — how the optimum moves with each number.
- [`reliability`][tripodjax.optimize.reliability] — the probability of missing each requirement
  under the spec's ``[uncertainty]`` (FORM, SORM, Monte Carlo, importance sampling).
- [`evaluate_catalogue`][tripodjax.optimize.evaluate_catalogue] — the GE/GI sizes under the spec.
"""

from tripodjax.optimize.problem import constraint_landscape, evaluate, evaluate_catalogue
from tripodjax.optimize.reliability import reliability
from tripodjax.optimize.sensitivity import sensitivities
from tripodjax.optimize.solver import Result, pareto_front, solve, solve_family
from tripodjax.optimize.spec import (
    DEFAULT_SPEC_TOML,
    QUANTITIES,
    VARIABLES,
    Spec,
    SpecError,
    load_spec,
    parse_spec,
)

__all__ = [
    "DEFAULT_SPEC_TOML",
    "QUANTITIES",
    "VARIABLES",
    "Result",
    "Spec",
    "SpecError",
    "constraint_landscape",
    "evaluate",
    "evaluate_catalogue",
    "load_spec",
    "pareto_front",
    "parse_spec",
    "reliability",
    "sensitivities",
    "solve",
    "solve_family",
]
