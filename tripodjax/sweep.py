"""Batch sweeps over many halfshaft layouts: jit + vmap, chunked, sharded over devices.

One compiled function evaluates a chunk of layouts; chunks keep memory bounded
for millions of layouts, and each chunk is split across every visible device
with JAX's own sharding (a 1-D mesh over the layouts). Multi-host: start every
process with ``jax.distributed.initialize()`` (see the JAX documentation),
then call [`sweep`][tripodjax.sweep.sweep] with the same ``layouts`` on every host; ``jax.devices()``
then spans all hosts and each chunk is split across all of them.
"""

import collections.abc
import functools
import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax import progress as progress_meters
from tripodjax import solvers
from tripodjax._checks import (
    check_choice,
    check_integer,
    check_layout_domain,
    check_non_negative,
    check_positive,
    check_sweep_batch,
)
from tripodjax.friction import (
    DEFAULT_STROKE_WIDTH,
    GAF_MODELS,
    GREASE_A,
    FrictionParams,
    _check_params,
    gaf_from_revolution,
)
from tripodjax.kinematics import (
    METRICS,
    NEEDS_RATES,
    _check_n_theta,
    metrics_from,
    raise_failure_of_revolution,
    revolution,
)
from tripodjax.layout import Layout, check_layout
from tripodjax.results import RESULTS, worst

KINEMATIC_OUTPUTS = METRICS
GAF_OUTPUTS = ("gaf_rms", "gaf_peak", "gaf_third_order")
OUTPUTS = KINEMATIC_OUTPUTS + GAF_OUTPUTS
STATUS_OUTPUTS = ("result", "converged")
DEFAULT_OUTPUTS = ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "converged", "result")
# Angles solved per compiled call: on a CPU a chunk's arrays should stay in cache (measured on
# a 2-core machine with 2 MiB L2 per core: 3× faster at 2^18 points than at 2^20); on an
# accelerator larger chunks fill the device.
DEFAULT_CHUNK_POINTS = {"cpu": 2**18}
DEFAULT_CHUNK_POINTS_ACCELERATOR = 2**22


class SweepResult(dict[str, np.ndarray]):
    """The outputs of [`sweep`][tripodjax.sweep.sweep]: a dict name → NumPy array of length N, plus a status summary.

    Attributes:
        result_counts: dict [`RESULTS`][tripodjax.results.RESULTS] name → number of
            layouts with that (worst) code, when the status was computed (an
            output ``"result"`` or ``"converged"``, or ``throw=True``); else None.
    """

    result_counts: dict[str, int] | None = None


def count_results(codes: ArrayLike) -> dict[str, int]:
    """Layouts per [`RESULTS`][tripodjax.results.RESULTS] code: dict name → count (every code listed)."""
    codes = np.asarray(codes)
    return {code.name: int(np.count_nonzero(codes == code)) for code in RESULTS}


def _check_layouts(layouts):
    check_layout(layouts, "layouts", "a Layout whose fields are 1-D arrays of one length")
    fields = {name: getattr(layouts, name) for name in ("R", "l", "gamma0")}
    shapes = {name: np.shape(value) for name, value in fields.items()}
    if any(len(shape) != 1 for shape in shapes.values()) or len(set(shapes.values())) != 1:
        raise ValueError(
            f"sweep needs a Layout whose fields are 1-D arrays of one length; got shapes {shapes}"
        )
    check_layout_domain(**fields, prefix="layouts.")
    return shapes["R"][0]


def _check_outputs(outputs: object, torque: object) -> tuple[str, ...]:
    allowed = f"a sequence of names among {', '.join(OUTPUTS)}"
    if isinstance(outputs, str | bytes):
        raise TypeError(
            f"outputs = {outputs!r} is a single string; allowed: {allowed}, e.g. ({outputs!r},)"
        )
    if not isinstance(outputs, collections.abc.Sequence):  # a dict, a set, a number…
        raise TypeError(
            f"outputs = {outputs!r} is not allowed; allowed: {allowed} (a tuple or list), "
            f"got a {type(outputs).__name__}"
        )
    outputs = tuple(outputs)
    unknown = [name for name in outputs if not isinstance(name, str) or name not in OUTPUTS]
    if unknown or not outputs:
        raise ValueError(
            f"outputs {unknown or outputs!r} not allowed; allowed: {', '.join(OUTPUTS)}"
        )
    if any(name in GAF_OUTPUTS for name in outputs) and torque is None:
        raise ValueError(
            f"outputs {', '.join(n for n in outputs if n in GAF_OUTPUTS)} need a torque [N·m]"
        )
    return tuple(dict.fromkeys(outputs))  # without repeats, in order


@functools.partial(jax.jit, static_argnames=("n_theta", "solver", "outputs", "gaf_model"))
def _evaluate_chunk(
    layouts, torque, friction_params, width, *, n_theta, solver, outputs, gaf_model
):
    kinematic = tuple(name for name in outputs if name in KINEMATIC_OUTPUTS)
    gaf_names = tuple(name for name in outputs if name in GAF_OUTPUTS)
    with_rates = bool(gaf_names) or any(name in NEEDS_RATES for name in kinematic)

    def one(layout):
        sol, rates = revolution(layout, n_theta, solver, with_rates=with_rates)
        result = metrics_from(layout, sol, rates, kinematic)
        if gaf_names:
            g = gaf_from_revolution(layout, sol, rates, torque, friction_params, gaf_model, width)
            result.update(gaf_rms=g.rms, gaf_peak=g.peak, gaf_third_order=g.third_order)
            if "result" in result:
                result["result"] = worst(result["result"], g.result)
                if "converged" in result:
                    result["converged"] = result["result"] == RESULTS.successful
        return {name: result[name] for name in outputs}

    return jax.vmap(one)(layouts)


def sweep(
    layouts: Layout,
    n_theta: int = 360,
    solver: solvers.SolverLike = "newton",
    outputs: Sequence[str] = DEFAULT_OUTPUTS,
    chunk_size: int | None = None,
    *,
    torque: ArrayLike | None = None,
    friction_params: FrictionParams = GREASE_A,
    gaf_model: str = "stroke",
    gaf_width: float = DEFAULT_STROKE_WIDTH,
    devices: Sequence[jax.Device] | None = None,
    progress: bool | progress_meters.ProgressMeter | None = None,
    throw: bool = False,
    fidelity: str | None | solvers._Unset = solvers._UNSET,
    rtol: float | None | solvers._Unset = solvers._UNSET,
    max_steps: int | solvers._Unset = solvers._UNSET,
) -> SweepResult:
    """Metrics of many layouts at once.

    Args:
        layouts: a [`Layout`][tripodjax.layout.Layout] whose fields are 1-D arrays of
            one length N (checked element by element against the layout
            domain; the error names the field and the index).
        n_theta: angles per revolution (a multiple of 6).
        solver: a [`tripodjax.solvers`][tripodjax.solvers] object or shorthand —
            ``"newton"`` (default), ``"analytic"``, ``"closed_form"`` (see
            [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics]).
        outputs: a sequence of names to compute — any
            [`KinematicMetrics`][tripodjax.kinematics.KinematicMetrics] field (including
            ``"result"``, the worst [`RESULTS`][tripodjax.results.RESULTS] code per
            layout, and ``"error_estimate"``, the per-layout error estimate of
            the solver level), and ``"gaf_rms"``, ``"gaf_peak"``,
            ``"gaf_third_order"`` [N] (these need ``torque``; their status
            joins ``"result"``). Only these are computed: dψ/dθ, for instance,
            only when ``"irregularity"`` or a GAF output is asked for. A bare
            string is a TypeError.
        chunk_size: layouts per compiled call, a positive integer, rounded up
            to a multiple of the device count; bounds the memory. Default: 2^18
            solved angles per chunk on a CPU (cache-sized: 2184 layouts at
            n_theta = 360), 2^22 on an accelerator.
        torque: GAF torque [N·m], finite and ≥ 0 (as [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft]).
        friction_params, gaf_model, gaf_width: GAF inputs, see
            [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft].
        devices: devices to split each chunk over (default: all visible).
        progress: ``None`` (a bar when standard error is a terminal and there
            is more than one chunk), ``True``/``False`` or a
            [`ProgressMeter`][tripodjax.progress.ProgressMeter].
        throw: raise [`SolverError`][tripodjax.solvers.SolverError] naming the first
            layout (index) and angle θ whose solve did not succeed.
        fidelity, rtol, max_steps: older spellings of ``solver``.

    Returns:
        [`SweepResult`][tripodjax.sweep.SweepResult]: a dict name → NumPy array of length N, with
        ``result_counts`` (layouts per result code) when ``"result"`` or
        ``"converged"`` is among the outputs or ``throw`` is set. The working
        dtype is that of the layout arrays.
    """
    n = _check_layouts(layouts)
    solver = solvers.resolve_legacy(solver, fidelity, rtol, max_steps)
    outputs = _check_outputs(outputs, torque)
    _check_n_theta(n_theta)
    if torque is not None:
        check_non_negative("torque", torque, " N·m")
    if chunk_size is not None:
        chunk_size = int(check_integer("chunk_size", chunk_size, minimum=1))
    _check_params(friction_params, "friction_params")
    check_choice("gaf_model", gaf_model, GAF_MODELS)
    check_positive(gaf_width=gaf_width)
    status = bool(throw) or any(name in STATUS_OUTPUTS for name in outputs)
    computed = outputs + (("result",) if status and "result" not in outputs else ())
    devices = check_sweep_batch(n, torque, devices)
    mesh = jax.sharding.Mesh(np.array(devices), ("layouts",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("layouts"))
    backend = devices[0].platform
    default_points = DEFAULT_CHUNK_POINTS.get(backend, DEFAULT_CHUNK_POINTS_ACCELERATOR)
    chunk = chunk_size or max(1, default_points // (n_theta // 3))
    chunk = max(len(devices), math.ceil(min(chunk, max(n, 1)) / len(devices)) * len(devices))
    fields = [np.asarray(getattr(layouts, name)) for name in ("R", "l", "gamma0")]
    n_chunks = math.ceil(n / chunk)
    if progress is None and n_chunks <= 1:
        progress = False
    bar = progress_meters.resolve(progress).start(total=n, desc="sweep", unit="layouts")
    static = dict(n_theta=n_theta, solver=solver, outputs=computed, gaf_model=gaf_model)
    pieces: dict[str, list[np.ndarray]] = {name: [] for name in computed}
    pending = None  # one chunk in flight while the next is dispatched (JAX runs asynchronously)

    def collect(done):
        result, count = done
        for name in computed:
            pieces[name].append(np.asarray(result[name])[:count])
        bar.update(count)

    try:
        for start in range(0, n, chunk):
            stop = min(start + chunk, n)
            # Pad the last chunk with copies of its last layout: one compiled shape throughout.
            index = np.minimum(np.arange(start, start + chunk), stop - 1)
            part = Layout(*(jax.device_put(f[index], sharding) for f in fields))
            dispatched = (
                _evaluate_chunk(part, torque, friction_params, gaf_width, **static),
                stop - start,
            )
            if pending is not None:
                collect(pending)
            pending = dispatched
        if pending is not None:
            collect(pending)
    finally:
        bar.close()
    out = {name: np.concatenate(pieces[name]) if pieces[name] else np.zeros(0) for name in computed}
    codes = out["result"] if status else None
    if throw and codes is not None and np.any(codes != RESULTS.successful):
        i = int(np.flatnonzero(codes != RESULTS.successful)[0])
        layout = Layout(*(jnp.asarray(f[i]) for f in fields))
        raise_failure_of_revolution(codes[i], layout, n_theta, solver, "sweep", index=i)
        raise solvers.SolverError(
            f"sweep: layout {i}: {RESULTS(int(codes[i])).name} "
            f"({RESULTS(int(codes[i])).describe()}) in the GAF over the revolution"
        )
    result = SweepResult((name, out[name]) for name in outputs)
    result.result_counts = count_results(codes) if codes is not None else None
    return result
