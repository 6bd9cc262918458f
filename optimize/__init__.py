"""The joint-design problem and its optimiser (``optimize-joint``).

- :func:`load_spec` — the design specification (TOML, checked; an embedded default).
- :func:`evaluate` — objective and constraint margins of one design (jit-compiled).
- :func:`solve` — the proposed joint size, by an augmented Lagrangian on optax's L-BFGS.
- :func:`solve_family`, :func:`pareto_front` — many scenarios at once through vmap.
"""

from tripodjax.optimize.problem import evaluate
from tripodjax.optimize.solver import Result, pareto_front, solve, solve_family
from tripodjax.optimize.spec import DEFAULT_SPEC_TOML, Spec, SpecError, load_spec, parse_spec

__all__ = [
    "DEFAULT_SPEC_TOML",
    "Result",
    "Spec",
    "SpecError",
    "evaluate",
    "load_spec",
    "pareto_front",
    "parse_spec",
    "solve",
    "solve_family",
]
