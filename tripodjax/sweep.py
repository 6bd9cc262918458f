"""Batch sweeps over many halfshaft layouts: jit + vmap, chunked, sharded over devices and processes.

One compiled function evaluates a chunk of layouts; chunks keep memory bounded
for millions of layouts, and each chunk is one global array split across every
device of ``jax.devices()`` (a 1-D mesh over the rows). Several processes
(hosts): start every process with ``jax.distributed.initialize()``, then call
[`sweep`][tripodjax.sweep.sweep] with the same ``layouts`` in every process;
each process places only its own devices' rows of a chunk
(``jax.make_array_from_callback``), evaluates its share, and every process
receives the whole result. [`map_chunks`][tripodjax.sweep.map_chunks] is the same
machinery for any row-wise function (e.g. a Monte Carlo of the design chain).
"""

import collections.abc
import functools
import math
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax import forces as force_model
from tripodjax import progress as progress_meters
from tripodjax import solvers
from tripodjax._checks import (
    check_devices,
    check_flag,
    check_instance,
    check_integer,
    check_layout_domain,
    check_one_number,
    check_sweep_batch,
)
from tripodjax._compile import SMALL_SWEEP_OPTIONS
from tripodjax.friction import GAFInputs, gaf_from_revolution
from tripodjax.kinematics import (
    FROM_SERIES,
    METRICS,
    NEEDS_RATES,
    _check_n_theta,
    metrics_and_window,
    raise_failure_of_revolution,
    revolution,
)
from tripodjax.layout import Layout, check_layout
from tripodjax.results import RESULTS, worst

KINEMATIC_OUTPUTS = METRICS
GAF_OUTPUTS = ("gaf_rms", "gaf_peak", "gaf_third_order")
# The force model's quantities (tripodjax.forces): the GAF names among them come from whichever
# of gaf= (Lee's friction) or forces= (the force model) is given; the others need forces=.
FORCE_OUTPUTS = force_model.QUANTITIES
FORCE_ONLY_OUTPUTS = tuple(name for name in FORCE_OUTPUTS if name not in GAF_OUTPUTS)
OUTPUTS = KINEMATIC_OUTPUTS + GAF_OUTPUTS + FORCE_ONLY_OUTPUTS
STATUS_OUTPUTS = ("result", "converged")
DEFAULT_OUTPUTS = ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "converged", "result")
# Angles solved per compiled call: on a CPU a chunk's arrays should stay in cache (measured on
# a 2-core machine with 2 MiB L2 per core: 3× faster at 2^18 points than at 2^20); on an
# accelerator larger chunks fill the device.
DEFAULT_CHUNK_POINTS = {"cpu": 2**18}
DEFAULT_CHUNK_POINTS_ACCELERATOR = 2**22
# Layouts per compiled call with the force model: its loop over the angles holds a few dozen
# arrays of 3 × the chunk's layouts each step, which on a CPU should stay in its L2 cache
# (measured on a 2-core AMD EPYC, 1 MiB L2 per core: every force quantity 1.4× faster at 1024
# layouts a chunk than at the 2184 of 2^18 points).
FORCE_CHUNK_LAYOUTS = 1024


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


def _check_concrete(what: str, inputs: object, instead: str) -> None:
    """A host-side driver's ``inputs`` are concrete: not traced by jax.jit, jax.grad or jax.vmap."""
    if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(inputs)):
        raise TypeError(
            f"{what} was called under a JAX transformation (jax.jit, jax.grad, jax.vmap, …); "
            "it runs outside them (it compiles its own chunks of rows and returns NumPy "
            f"arrays): {instead}"
        )


def _check_outputs(outputs: object, gaf: object, forces: object) -> tuple[str, ...]:
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
    if not outputs:
        raise ValueError(f"outputs is empty; allowed: {allowed}, at least one")
    unknown = [name for name in outputs if not isinstance(name, str) or name not in OUTPUTS]
    if unknown:
        raise ValueError(f"outputs {unknown!r} not allowed; allowed: {', '.join(OUTPUTS)}")
    gaf_names = ", ".join(n for n in outputs if n in GAF_OUTPUTS)
    if gaf is not None and forces is not None:  # one would be left unused, without a word
        named = f"outputs {gaf_names} come" if gaf_names else "the GAF outputs come"
        raise ValueError(
            f"{named} from gaf= (Lee's friction) or from forces= (the force model), not both; "
            "allowed: one of the two (the force outputs take forces=)"
        )
    if gaf_names and gaf is None and forces is None:
        raise ValueError(
            f"outputs {gaf_names} need gaf=GAFInputs(torque, ...) (Lee's friction: torque "
            "[N·m], friction constants, model, width) or forces=ForceInputs(torque, ...) "
            "(the force model)"
        )
    force_names = ", ".join(n for n in outputs if n in FORCE_ONLY_OUTPUTS)
    if force_names and forces is None:
        raise ValueError(
            f"outputs {force_names} need forces=ForceInputs(torque, ...) (the force model: "
            "torque [N·m], friction, plunge speed)"
        )
    return tuple(dict.fromkeys(outputs))  # without repeats, in order


# Keywords sweep no longer takes, each with what replaces it (a one-line TypeError names it).
REMOVED_KEYWORDS = {
    "fidelity": "solver= (a string shorthand or a solver object)",
    "rtol": "solver=tj.Newton(rtol=..., max_steps=...)",
    "max_steps": "solver=tj.Newton(rtol=..., max_steps=...)",
    "torque": "gaf=tj.GAFInputs(torque, params, model, width)",
    "friction_params": "gaf=tj.GAFInputs(torque, params=...)",
    "gaf_model": "gaf=tj.GAFInputs(torque, model=...)",
    "gaf_width": "gaf=tj.GAFInputs(torque, width=...)",
}


def _reject_removed(what: str, keywords: dict[str, object]) -> None:
    for name in keywords:
        if name in REMOVED_KEYWORDS:
            raise TypeError(
                f"{what}: the keyword {name}= was removed; use {REMOVED_KEYWORDS[name]}"
            )
        raise TypeError(f"{what}() got an unexpected keyword argument {name!r}")


def _evaluate_chunk(layouts, gaf, forces, *, n_theta, solver, outputs):
    kinematic = tuple(name for name in outputs if name in KINEMATIC_OUTPUTS)
    # The GAF names from the force model when forces= is given (sweep allows one of the two).
    force_names = tuple(name for name in outputs if name in FORCE_OUTPUTS and forces is not None)
    gaf_names = tuple(name for name in outputs if name in GAF_OUTPUTS and forces is None)
    with_rates = bool(gaf_names or force_names) or any(name in NEEDS_RATES for name in kinematic)

    def solve(layout):
        return revolution(layout, n_theta, solver, with_rates=with_rates)

    def metrics(layout, solved, extremes):
        return metrics_and_window(layout, *solved, kinematic, extremes)

    # A series' extremes (an interpolating level) from a few angles where that provably
    # gives every angle's, which holds over the layout domain; else the chunk's metrics again
    # at every angle, from the same solve (compiled once).
    solved = jax.vmap(solve)(layouts)
    result, window_holds = jax.vmap(functools.partial(metrics, extremes="window"))(layouts, solved)
    if window_holds is not None:
        result = jax.lax.cond(
            jnp.all(window_holds),
            lambda: result,
            lambda: jax.vmap(functools.partial(metrics, extremes="grid"))(layouts, solved)[0],
        )
    codes = []  # the status of the GAF or the forces joins "result"
    if gaf_names:
        g = jax.vmap(lambda layout, s: gaf_from_revolution(layout, *s, gaf))(layouts, solved)
        result.update(gaf_rms=g.rms, gaf_peak=g.peak, gaf_third_order=g.third_order)
        codes.append(g.result)
    if force_names:
        f = force_model.force_quantities(layouts, *solved, forces, force_names + ("result",))
        codes.append(f.pop("result"))
        result.update(f)
    if codes and "result" in result:
        result["result"] = worst(result["result"], *codes)
        if "converged" in result:
            result["converged"] = result["result"] == RESULTS.successful
    return {name: result[name] for name in outputs}


# A sweep's chunk program: up to ``SMALL_SWEEP`` solved points (1092 layouts at newton and
# n_theta = 360, 10 922 where every output comes from the analytic level's series) it runs for
# milliseconds and is compiled with ``SMALL_SWEEP_OPTIONS``: its first call 0.3-0.4 s sooner,
# each call up to 1.5× longer. Larger sweeps keep XLA's defaults (throughput).
SMALL_SWEEP = 1 << 17
_CHUNK_STATIC = ("n_theta", "solver", "outputs")
_evaluate_for_throughput = jax.jit(_evaluate_chunk, static_argnames=_CHUNK_STATIC)
_evaluate_for_latency = jax.jit(
    _evaluate_chunk, static_argnames=_CHUNK_STATIC, compiler_options=SMALL_SWEEP_OPTIONS
)


def default_chunk_size(points_per_row: int, devices: Sequence[jax.Device] | None = None) -> int:
    """Rows per compiled call for a row of ``points_per_row`` solved points: 2^18 points on a CPU, 2^22 on an accelerator."""
    platform = (list(devices) if devices is not None else jax.devices())[0].platform
    points = DEFAULT_CHUNK_POINTS.get(platform, DEFAULT_CHUNK_POINTS_ACCELERATOR)
    return max(1, points // max(1, points_per_row))


def _points_per_layout(
    n_theta: int, solver: object, outputs: Sequence[str], forces: bool = False
) -> int:
    """A layout's points in a chunk: its period's n_theta/3 solved angles, or for a level
    that solves at nodes, when every output comes from the node series, the nodes solved
    (half of them) and the error estimate's samples (as many as the nodes). The few
    angles of the series' extremes cost little beside them: measured at n_theta = 36,
    360 and 3600, the cost per layout is flat from about 10 000 layouts a chunk to 40 000
    (21 845 with the default 8 nodes), 1.2× that at 5000, the compiled call's own
    overhead then spread over fewer layouts. With ``forces`` (the force model's outputs),
    enough points for at most ``FORCE_CHUNK_LAYOUTS`` layouts in a CPU's chunk."""
    nodes = getattr(solver, "nodes", None)
    period = n_theta // 3
    if forces:  # at most FORCE_CHUNK_LAYOUTS layouts in a CPU's chunk
        return max(period, DEFAULT_CHUNK_POINTS["cpu"] // FORCE_CHUNK_LAYOUTS)
    if nodes is None or period <= nodes or any(name not in FROM_SERIES for name in outputs):
        return period
    return nodes // 2 + nodes


def _gather(leaf: jax.Array, count: int) -> np.ndarray:
    """A chunk's output as a NumPy array on this process, its first ``count`` rows."""
    if leaf.is_fully_addressable:
        return np.asarray(leaf)[:count]
    # Rows on other processes' devices: every process receives the whole chunk.
    from jax.experimental import multihost_utils

    return np.asarray(multihost_utils.process_allgather(leaf, tiled=True))[:count]


def _check_rows(out: Any, rows: int) -> Any:
    """``out`` unless a leaf of ``fn``'s output lacks the chunk's leading length ``rows`` (row by row)."""
    leaves = jax.tree_util.tree_leaves_with_path(out)
    bad = [(path, np.shape(leaf)) for path, leaf in leaves if np.shape(leaf)[:1] != (rows,)]
    if bad:
        path, shape = bad[0]
        raise ValueError(
            f"map_chunks: fn's output{jax.tree_util.keystr(path)} has shape {shape} for a chunk "
            f"of {rows} rows; "
            f"allowed: every output leaf with leading length {rows}, row i from input row i"
        )
    return out


def map_chunks(
    fn: Callable[[Any], Any],
    inputs: Any,
    chunk_size: int,
    *,
    devices: Sequence[jax.Device] | None = None,
    progress: bool | progress_meters.ProgressMeter | None = None,
    desc: str = "batch",
    unit: str = "rows",
) -> Any:
    """Evaluate a row-wise function over N rows in chunks: bounded memory, split over devices and processes.

    The machinery of [`sweep`][tripodjax.sweep.sweep], for any batch evaluation
    (e.g. a Monte Carlo of the design chain): each chunk of ``chunk_size`` rows
    is one global array over a 1-D mesh of ``devices`` (default
    ``jax.devices()``, which spans every process after
    ``jax.distributed.initialize()``); each process places only its own
    devices' rows, the chunk is evaluated where it lies, and every process
    receives the whole output. One chunk is in flight while the next is
    dispatched. The last chunk is padded with copies of the last row (one
    compiled shape throughout).

    Args:
        fn: a function of a pytree of arrays with leading axis ``chunk_size``
            to a pytree of arrays with the same leading axis, row by row (row i
            of the output depends on row i of the input only, e.g. a
            ``jax.jit`` of a ``jax.vmap``); jit-compiled once per shape.
        inputs: a pytree of NumPy-convertible arrays with one leading length
            N, the same in every process.
        chunk_size: the most rows per call, a positive integer: the N rows
            go in the fewest calls of at most that many, spread evenly over them
            and rounded up to a multiple of the device count (see
            [`default_chunk_size`][tripodjax.sweep.default_chunk_size]).
        devices: devices of the mesh (default: all, across processes).
        progress: as for [`sweep`][tripodjax.sweep.sweep] (a bar on process 0 only).
        desc, unit: the progress bar's labels.

    Returns:
        ``fn``'s output pytree with NumPy leaves of leading length N.
    """
    _check_concrete("map_chunks", inputs, "call fn itself inside the transformation")
    chunk_size = int(check_integer("chunk_size", chunk_size, minimum=1))
    leaves, treedef = jax.tree_util.tree_flatten(inputs)
    leaves = [np.asarray(leaf) for leaf in leaves]
    lengths = {leaf.shape[0] if leaf.ndim else -1 for leaf in leaves}
    if len(lengths) != 1 or -1 in lengths:
        shapes = [leaf.shape for leaf in leaves]
        raise ValueError(
            f"map_chunks needs inputs whose leaves share one leading length; got shapes {shapes}"
        )
    n = lengths.pop()
    devices = check_devices(devices)
    mesh = jax.sharding.Mesh(np.array(devices), ("rows",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("rows"))
    # The fewest calls of at most chunk_size rows, the rows spread evenly over them (so the
    # padding of the last call is under one row per device, not most of a chunk).
    calls = math.ceil(max(n, 1) / min(chunk_size, max(n, 1)))
    chunk = len(devices) * max(1, math.ceil(math.ceil(max(n, 1) / calls) / len(devices)))
    if n == 0:
        shapes = [jax.ShapeDtypeStruct((chunk, *leaf.shape[1:]), leaf.dtype) for leaf in leaves]
        out = _check_rows(jax.eval_shape(fn, jax.tree_util.tree_unflatten(treedef, shapes)), chunk)
        return jax.tree_util.tree_map(lambda s: np.zeros((0, *s.shape[1:]), s.dtype), out)
    if progress is None and n <= chunk:
        progress = False
    if jax.process_index() != 0:
        progress = False
    bar = progress_meters.resolve(progress).start(total=n, desc=desc, unit=unit)
    pieces: list[Any] = []
    pending = None  # one chunk in flight while the next is dispatched (JAX runs asynchronously)

    def place(part):
        # Each process builds only the shards of its own devices.
        return jax.make_array_from_callback(part.shape, sharding, lambda index: part[index])

    def collect(done):
        result, count = done
        pieces.append(jax.tree_util.tree_map(lambda leaf: _gather(leaf, count), result))
        bar.update(count)

    try:
        for start in range(0, n, chunk):
            stop = min(start + chunk, n)
            index = np.minimum(np.arange(start, start + chunk), stop - 1)
            part = jax.tree_util.tree_unflatten(treedef, [place(leaf[index]) for leaf in leaves])
            dispatched = (_check_rows(fn(part), chunk), stop - start)
            if pending is not None:
                collect(pending)
            pending = dispatched
        if pending is not None:
            collect(pending)
    finally:
        bar.close()
    return jax.tree_util.tree_map(lambda *parts: np.concatenate(parts), *pieces)


def sweep(
    layouts: Layout,
    n_theta: int = 360,
    solver: solvers.SolverLike = "newton",
    outputs: Sequence[str] = DEFAULT_OUTPUTS,
    chunk_size: int | None = None,
    *,
    gaf: GAFInputs | None = None,
    forces: force_model.ForceInputs | None = None,
    devices: Sequence[jax.Device] | None = None,
    progress: bool | progress_meters.ProgressMeter | None = None,
    throw: bool = False,
    **removed: object,
) -> SweepResult:
    """Metrics of many layouts at once.

    Args:
        layouts: a [`Layout`][tripodjax.layout.Layout] whose fields are 1-D arrays of
            one length N (checked element by element against the layout
            domain; the error names the field and the index).
        n_theta: angles per revolution (a multiple of 6; with a GAF or force output at
            least 24, `tripodjax.kinematics.MIN_N_THETA_ORDERS`).
        solver: a [`tripodjax.solvers`][tripodjax.solvers] object, which carries
            its settings, or a shorthand — ``"newton"`` (default),
            ``"analytic"``, ``"closed_form"`` (see
            [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics]).
        outputs: a sequence of names to compute — any
            [`KinematicMetrics`][tripodjax.kinematics.KinematicMetrics] field (including
            ``"result"``, the worst [`RESULTS`][tripodjax.results.RESULTS] code per
            layout, and ``"error_estimate"``, the per-layout error estimate of
            the solver level), and ``"gaf_rms"``, ``"gaf_peak"``,
            ``"gaf_third_order"`` [N] (these need ``gaf`` or ``forces``), and
            the force model's quantities (these need ``forces``); the status
            of the GAF or the forces joins ``"result"``. Only these are computed, each at its level's
            cost (the cost table of the documentation's "Speed and accuracy" page): dψ/dθ only for
            ``"irregularity"`` and the GAF; under ``analytic`` and
            ``closed_form`` the status and error estimate from the nodes and
            midway between them; ``"max_residual"`` evaluates the pair at
            every angle (as much as the analytic solve itself). A bare string
            is a TypeError.
        chunk_size: the most layouts per compiled call, a positive integer
            (the layouts are spread evenly over the calls, rounded up to a
            multiple of the device count); bounds the memory. Default: 2^18
            solved angles per chunk on a CPU (cache-sized: 2184 layouts at
            n_theta = 360), 2^22 on an accelerator; a level that solves at
            nodes counts its solved nodes and error-estimate samples instead
            when every output comes from the series (21 845 layouts with the
            default 8 nodes, at any n_theta).
        gaf: the GAF inputs, a [`GAFInputs`][tripodjax.friction.GAFInputs]
            (torque, friction constants, model, width; one number per field, for
            every layout), for the GAF outputs from Lee's empirical friction
            (seed 3.2.15).
        forces: the force model's inputs, a [`ForceInputs`][tripodjax.forces.ForceInputs]
            (one number per field, for every layout), for its outputs
            ``"gaf_sixth_order"``, ``"gaf_ninth_order"``, ``"lts_mean"``,
            ``"lts_ripple"``, ``"complementary_torque_steady"``,
            ``"complementary_torque_third_order"``,
            ``"complementary_torque_sixth_order"``, ``"roller_load_ratio"``,
            ``"friction_power"`` (see [`force_quantities`][tripodjax.forces.force_quantities]);
            given, the GAF outputs come from the force model too (``gaf`` and
            ``forces`` together with a GAF output is a ValueError).
        devices: devices to split each chunk over (default ``jax.devices()``:
            all devices of all processes).
        progress: ``None`` (a bar when standard error is a terminal and there
            is more than one chunk), ``True``/``False`` or a
            [`ProgressMeter`][tripodjax.progress.ProgressMeter].
        throw: raise [`SolverError`][tripodjax.solvers.SolverError] naming the first
            layout (index) and angle θ whose solve did not succeed.

    The keywords ``fidelity``, ``rtol``, ``max_steps``, ``torque``,
    ``friction_params``, ``gaf_model`` and ``gaf_width`` were removed (0.x):
    each raises a one-line TypeError naming its replacement.

    Returns:
        [`SweepResult`][tripodjax.sweep.SweepResult]: a dict name → NumPy array of length N, with
        ``result_counts`` (layouts per result code) when ``"result"`` or
        ``"converged"`` is among the outputs or ``throw`` is set. The working
        dtype is that of the layout arrays.

    A host-side driver: it runs outside ``jax.jit``, ``jax.grad`` and ``jax.vmap`` (a
    TypeError says so). For derivatives, differentiate
    [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics],
    [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft] or
    [`forces_halfshaft`][tripodjax.forces.forces_halfshaft] of one layout, with ``jax.vmap``
    over the layouts.
    """
    if removed:
        _reject_removed("sweep", removed)
    _check_concrete(
        "sweep",
        (layouts, gaf, forces),
        "for derivatives or inside jax.jit, take kinematic_metrics, gaf_halfshaft or "
        "forces_halfshaft of one layout, with jax.vmap over the layouts",
    )
    n = _check_layouts(layouts)
    check_flag("throw", throw)
    solver = solvers.resolve(solver)
    outputs = _check_outputs(outputs, gaf, forces)
    n_theta = _check_n_theta(n_theta)
    if gaf is not None:
        check_instance("gaf", gaf, GAFInputs, "a GAFInputs, e.g. tj.GAFInputs(torque=500.0)")
        check_one_number("gaf", gaf, "one number for every layout (shape ())")
    if forces is not None:
        check_instance(
            "forces", forces, force_model.ForceInputs, "a ForceInputs, e.g. tj.ForceInputs(500.0)"
        )
        check_one_number("forces", forces, "one number for every layout (shape ())")
    if chunk_size is not None:
        chunk_size = int(check_integer("chunk_size", chunk_size, minimum=1))
    devices = check_sweep_batch(n, None if gaf is None else gaf.torque, devices)
    status = bool(throw) or any(name in STATUS_OUTPUTS for name in outputs)
    computed = outputs + (("result",) if status and "result" not in outputs else ())
    uses_forces = any(name in FORCE_OUTPUTS for name in computed) and forces is not None
    uses_gaf = any(name in GAF_OUTPUTS for name in computed) and not uses_forces
    if uses_forces or uses_gaf:
        _check_n_theta(n_theta, orders="the GAF and force outputs")
    points = _points_per_layout(n_theta, solver, computed, uses_forces)
    small = n * points <= SMALL_SWEEP
    evaluate = functools.partial(
        _evaluate_for_latency if small else _evaluate_for_throughput,
        gaf=gaf if uses_gaf else None,
        forces=forces if uses_forces else None,
        n_theta=n_theta,
        solver=solver,
        outputs=computed,
    )
    chunk = chunk_size or default_chunk_size(points, devices)
    out = map_chunks(
        evaluate, layouts, chunk, devices=devices, progress=progress, desc="sweep", unit="layouts"
    )
    codes = out["result"] if status else None
    if throw and codes is not None and np.any(codes != RESULTS.successful):
        i = int(np.flatnonzero(codes != RESULTS.successful)[0])
        layout = Layout(
            *(jnp.asarray(np.asarray(getattr(layouts, f))[i]) for f in ("R", "l", "gamma0"))
        )
        raise_failure_of_revolution(codes[i], layout, n_theta, solver, "sweep", index=i)
        raise solvers.SolverError(
            f"sweep: layout {i}: {RESULTS(int(codes[i])).name} "
            f"({RESULTS(int(codes[i])).describe()}) in the "
            f"{'forces' if uses_forces else 'GAF'} over the revolution"
        )
    result = SweepResult((name, out[name]) for name in outputs)
    result.result_counts = count_results(codes) if codes is not None else None
    return result
