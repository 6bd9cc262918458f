"""tripodjax: differentiable design optimisation of tripod constant-velocity joints.

Units: lengths in mm, angles in rad, torque in N·m, pressure in MPa (degrees
only at the user-facing edge). Physics layers, after the seed thesis:

- [`tripodjax.layout`][tripodjax.layout]: [`Layout`][tripodjax.layout.Layout] (R, l, γ0) and the seed's Table 2.1 cases.
- [`tripodjax.joint`][tripodjax.joint]: single-joint relations (§2.3–2.6).
- [`tripodjax.halfshaft`][tripodjax.halfshaft]: the halfshaft residual pair solved per θ (§2.9).
- [`tripodjax.kinematics`][tripodjax.kinematics]: metrics over a revolution (§2.10, §2.11.3).
- [`tripodjax.motion`][tripodjax.motion]: velocities and accelerations, exact and first order (§2.11).
- [`tripodjax.sweep`][tripodjax.sweep]: batch sweeps over layouts, chunked and sharded.
- [`tripodjax.friction`][tripodjax.friction]: friction and the generated axial force, GAF (§3.2).
- [`tripodjax.forces`][tripodjax.forces]: the rollers' forces from statics: GAF, LTS, complementary torque (§3.1).
- [`tripodjax.hertz`][tripodjax.hertz]: Hertz contact, torque capacities, minimum size (§4.2).
- [`tripodjax.life`][tripodjax.life]: load spectrum, working conditions, angle derating, Miner's rule (§4.2).
- [`tripodjax.vehicle`][tripodjax.vehicle]: the customer's vehicle → the joint's load cycles (§4.3).
- [`tripodjax.shaft`][tripodjax.shaft]: the shaft's sections and stems, statically and in fatigue (§4.3).
- [`tripodjax.outboard`][tripodjax.outboard]: the outboard fixed ball joint's capacities and life (§4.3).
- [`tripodjax.catalogue`][tripodjax.catalogue]: GE and GI catalogue sizes (§1.1.2).
- [`tripodjax.solvers`][tripodjax.solvers]: solver options (`Newton`, `Analytic`, `ClosedForm`).
- [`tripodjax.results`][tripodjax.results]: the `RESULTS` codes carried from the Newton point to every result.
- [`tripodjax.progress`][tripodjax.progress]: pluggable progress meters (tqdm).
- [`tripodjax.optimize`][tripodjax.optimize]: the design problem, its optimiser and ``optimize-joint``.

Nothing here changes JAX's global configuration: enable float64 yourself with
``jax.config.update("jax_enable_x64", True)`` when you need it.
"""

import importlib
import typing

from tripodjax import _lazy

# The package's attributes are imported on first use (PEP 562): ``import tripodjax`` itself
# loads neither JAX nor NumPy, so a command built on it (``optimize-joint``) installs its
# signal handlers and answers ``--help`` before the heavy imports.
_ATTRIBUTES = {
    "RESULTS": "tripodjax.results",
    "Analytic": "tripodjax.solvers",
    "ClosedForm": "tripodjax.solvers",
    "Newton": "tripodjax.solvers",
    "SolverError": "tripodjax.solvers",
    "HalfshaftSolution": "tripodjax.halfshaft",
    "solve_halfshaft": "tripodjax.halfshaft",
    "KinematicMetrics": "tripodjax.kinematics",
    "kinematic_metrics": "tripodjax.kinematics",
    "TABLE_2_1": "tripodjax.layout",
    "Layout": "tripodjax.layout",
    "seed_case": "tripodjax.layout",
    "JointMotion": "tripodjax.motion",
    "first_order_motion": "tripodjax.motion",
    "halfshaft_motion": "tripodjax.motion",
    "sweep": "tripodjax.sweep",
    "map_chunks": "tripodjax.sweep",
    "GAFInputs": "tripodjax.friction",
    "ForceInputs": "tripodjax.forces",
}
_SUBMODULES = (
    "catalogue",
    "forces",
    "friction",
    "halfshaft",
    "hertz",
    "joint",
    "kinematics",
    "layout",
    "life",
    "motion",
    "outboard",
    "progress",
    "results",
    "shaft",
    "solvers",
    "vehicle",
)

if typing.TYPE_CHECKING:  # what the lazy attributes are, for type checkers and the docs
    from tripodjax import (
        catalogue,
        forces,
        friction,
        hertz,
        joint,
        life,
        outboard,
        progress,
        shaft,
        solvers,
        vehicle,
    )
    from tripodjax.forces import ForceInputs
    from tripodjax.friction import GAFInputs
    from tripodjax.halfshaft import HalfshaftSolution, solve_halfshaft
    from tripodjax.kinematics import KinematicMetrics, kinematic_metrics
    from tripodjax.layout import TABLE_2_1, Layout, seed_case
    from tripodjax.motion import JointMotion, first_order_motion, halfshaft_motion
    from tripodjax.results import RESULTS
    from tripodjax.solvers import Analytic, ClosedForm, Newton, SolverError
    from tripodjax.sweep import map_chunks, sweep

    __version__: str


def __getattr__(name: str) -> typing.Any:
    value: typing.Any
    if name == "__version__":
        value = _version()
    elif name in _SUBMODULES:
        value = importlib.import_module(f"tripodjax.{name}")
    elif name in _ATTRIBUTES:
        value = getattr(importlib.import_module(_ATTRIBUTES[name]), name)
    else:
        raise AttributeError(f"module 'tripodjax' has no attribute {name!r}")
    globals()[name] = value  # later look-ups skip this function
    return value


_lazy.keep_functions(__name__, ["sweep"])


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__) | {"__version__"})


def _version() -> str:
    """One version: the installed metadata, which pyproject.toml takes from tripodjax/_version.py."""
    import importlib.metadata

    try:
        return importlib.metadata.version("tripodjax")
    except importlib.metadata.PackageNotFoundError:  # a source tree that is not installed
        from tripodjax._version import version

        return version


__all__ = [
    "RESULTS",
    "Analytic",
    "ClosedForm",
    "ForceInputs",
    "GAFInputs",
    "Newton",
    "SolverError",
    "progress",
    "solvers",
    "HalfshaftSolution",
    "JointMotion",
    "KinematicMetrics",
    "Layout",
    "TABLE_2_1",
    "catalogue",
    "first_order_motion",
    "forces",
    "friction",
    "halfshaft_motion",
    "hertz",
    "joint",
    "life",
    "outboard",
    "shaft",
    "kinematic_metrics",
    "map_chunks",
    "seed_case",
    "solve_halfshaft",
    "sweep",
    "vehicle",
]
