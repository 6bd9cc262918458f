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
- [`write_report`][tripodjax.optimize.write_report] — report.json, report.html and report.xlsx.
- [`life_report`][tripodjax.optimize.life_report] — the life of a design, its damage by condition, gear and mode.
- [`halfshaft_report`][tripodjax.optimize.halfshaft_report] — the rest of the halfshaft: the
  shaft's sections statically and in fatigue, and the outboard ball joint (seed §4.3).
- [`forces_report`][tripodjax.optimize.forces_report] — the forces inside the joint of a design
  (GAF, LTS, complementary torque, roller loads; seed §3.1).
"""

import importlib
import typing

from tripodjax import _lazy

# Imported on first use (PEP 562), so that ``optimize-joint`` starts without JAX (see
# ``tripodjax/__init__.py``).
_ATTRIBUTES = {
    "constraint_landscape": "problem",
    "write_report": "document",
    "evaluate": "problem",
    "evaluate_catalogue": "problem",
    "forces_report": "problem",
    "halfshaft_report": "structural",
    "life_report": "problem",
    "reliability": "reliability",
    "sensitivities": "sensitivity",
    "Result": "solver",
    "pareto_front": "solver",
    "solve": "solver",
    "solve_family": "solver",
    "DEFAULT_SPEC_TOML": "spec",
    "QUANTITIES": "spec",
    "VARIABLES": "spec",
    "Spec": "spec",
    "SpecError": "spec",
    "load_spec": "spec",
    "parse_spec": "spec",
}

if typing.TYPE_CHECKING:  # what the lazy attributes are, for type checkers and the docs
    from tripodjax.optimize.document import write_report
    from tripodjax.optimize.problem import (
        constraint_landscape,
        evaluate,
        evaluate_catalogue,
        forces_report,
        life_report,
    )
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
    from tripodjax.optimize.structural import halfshaft_report


def __getattr__(name: str) -> typing.Any:
    if name not in _ATTRIBUTES:
        raise AttributeError(f"module 'tripodjax.optimize' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"tripodjax.optimize.{_ATTRIBUTES[name]}"), name)
    globals()[name] = value  # later look-ups skip this function
    return value


_lazy.keep_functions(__name__, ["reliability"])


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


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
    "forces_report",
    "halfshaft_report",
    "life_report",
    "load_spec",
    "pareto_front",
    "parse_spec",
    "reliability",
    "sensitivities",
    "solve",
    "solve_family",
    "write_report",
]
