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
- [`tripodjax.hertz`][tripodjax.hertz]: Hertz contact, torque capacities, minimum size, life (§4.2).
- [`tripodjax.catalogue`][tripodjax.catalogue]: GE and GI catalogue sizes (§1.1.2).
- [`tripodjax.solvers`][tripodjax.solvers]: solver options (`Newton`, `Analytic`, `ClosedForm`).
- [`tripodjax.results`][tripodjax.results]: the `RESULTS` codes carried from the Newton point to every result.
- [`tripodjax.progress`][tripodjax.progress]: pluggable progress meters (tqdm).
- [`tripodjax.optimize`][tripodjax.optimize]: the design problem, its optimiser and ``optimize-joint``.

Nothing here changes JAX's global configuration: enable float64 yourself with
``jax.config.update("jax_enable_x64", True)`` when you need it.
"""

import importlib.metadata

from tripodjax import catalogue, friction, hertz, joint, progress, solvers
from tripodjax.friction import GAFInputs
from tripodjax.halfshaft import HalfshaftSolution, solve_halfshaft
from tripodjax.kinematics import KinematicMetrics, kinematic_metrics
from tripodjax.layout import TABLE_2_1, Layout, seed_case
from tripodjax.motion import JointMotion, first_order_motion, halfshaft_motion
from tripodjax.results import RESULTS
from tripodjax.solvers import Analytic, ClosedForm, Newton, SolverError
from tripodjax.sweep import map_chunks, sweep

try:  # one version: the installed metadata, which pyproject.toml takes from tripodjax/_version.py
    __version__ = importlib.metadata.version("tripodjax")
except importlib.metadata.PackageNotFoundError:  # a source tree that is not installed
    from tripodjax._version import version as __version__  # noqa: F401

__all__ = [
    "RESULTS",
    "Analytic",
    "ClosedForm",
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
    "friction",
    "halfshaft_motion",
    "hertz",
    "joint",
    "kinematic_metrics",
    "map_chunks",
    "seed_case",
    "solve_halfshaft",
    "sweep",
]
