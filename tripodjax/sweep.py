"""Batch sweeps over many halfshaft layouts: jit + vmap, chunked, sharded over devices.

One compiled function evaluates a chunk of layouts; chunks keep memory bounded
for millions of layouts, and each chunk is split across every visible device
with JAX's own sharding (a 1-D mesh over the layouts). Multi-host: start every
process with ``jax.distributed.initialize()`` (see the JAX documentation),
then call :func:`sweep` with the same ``layouts`` on every host; ``jax.devices()``
then spans all hosts and each chunk is split across all of them.
"""

import functools
import math
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from tripodjax._checks import concrete
from tripodjax.friction import DEFAULT_STROKE_WIDTH, GAF_MODELS, GREASE_A, gaf_from_revolution
from tripodjax.halfshaft import DEFAULT_MAX_STEPS
from tripodjax.kinematics import (
    NEEDS_RATES,
    KinematicMetrics,
    check_fidelity,
    metrics_from,
    period_grid,
    revolution,
)
from tripodjax.layout import MAX_GAMMA0, MAX_R_OVER_L, Layout

KINEMATIC_OUTPUTS = tuple(KinematicMetrics.__dataclass_fields__)
GAF_OUTPUTS = ("gaf_rms", "gaf_peak", "gaf_third_order")
OUTPUTS = KINEMATIC_OUTPUTS + GAF_OUTPUTS
DEFAULT_OUTPUTS = ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "converged")
# Angles solved per compiled call: on a CPU a chunk's arrays should stay in cache (measured on
# a 2-core machine with 2 MiB L2 per core: 3× faster at 2^18 points than at 2^20); on an
# accelerator larger chunks fill the device.
DEFAULT_CHUNK_POINTS = {"cpu": 2**18}
DEFAULT_CHUNK_POINTS_ACCELERATOR = 2**22


class _Progress:
    """A one-line progress bar on standard error; silent when that is no terminal."""

    def __init__(self, total, enabled):
        self.total, self.enabled, self.start = total, enabled, time.perf_counter()

    def update(self, done):
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        rate = done / elapsed if elapsed > 0 else 0.0
        bar = "#" * int(30 * done / self.total)
        sys.stderr.write(
            f"\rsweep [{bar:<30}] {done}/{self.total} layouts, {elapsed:.1f} s, {rate:.0f} layouts/s"
        )
        if done >= self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _check_layouts(layouts):
    fields = {name: getattr(layouts, name) for name in ("R", "l", "gamma0")}
    shapes = {name: np.shape(value) for name, value in fields.items()}
    if any(len(shape) != 1 for shape in shapes.values()) or len(set(shapes.values())) != 1:
        raise ValueError(
            f"sweep needs a Layout whose fields are 1-D arrays of one length; got shapes {shapes}"
        )
    arrays = {name: concrete(value) for name, value in fields.items()}
    rules = {
        "R": (lambda a: np.isfinite(a) & (a > 0), "R > 0 mm"),
        "l": (lambda a: np.isfinite(a) & (a > 0), "l > 0 mm"),
        "gamma0": (
            lambda a: np.isfinite(a) & (a >= 0) & (a <= MAX_GAMMA0),
            "0 ≤ gamma0 ≤ π/4 rad (45°)",
        ),
    }
    for name, (ok, allowed) in rules.items():
        bad = np.flatnonzero(~ok(arrays[name]))
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"layouts.{name}[{i}] = {float(arrays[name][i])!r} is outside the allowed range: {allowed}"
            )
    bad = np.flatnonzero(arrays["R"] / arrays["l"] > MAX_R_OVER_L)
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"layouts.R[{i}] / layouts.l[{i}] = {float(arrays['R'][i] / arrays['l'][i]):.4g} is outside the allowed range: R/l ≤ {MAX_R_OVER_L}"
        )
    return shapes["R"][0]


def _check_outputs(outputs, torque):
    outputs = tuple(outputs)
    unknown = [name for name in outputs if name not in OUTPUTS]
    if unknown or not outputs:
        raise ValueError(
            f"outputs {unknown or outputs!r} not allowed; allowed: {', '.join(OUTPUTS)}"
        )
    if any(name in GAF_OUTPUTS for name in outputs) and torque is None:
        raise ValueError(
            f"outputs {', '.join(n for n in outputs if n in GAF_OUTPUTS)} need a torque [N·m]"
        )
    return outputs


@functools.partial(
    jax.jit, static_argnames=("n_theta", "fidelity", "outputs", "gaf_model", "max_steps")
)
def _evaluate_chunk(
    layouts,
    torque,
    friction_params,
    width,
    rtol,
    *,
    n_theta,
    fidelity,
    outputs,
    gaf_model,
    max_steps,
):
    kinematic = tuple(name for name in outputs if name in KINEMATIC_OUTPUTS)
    gaf_names = tuple(name for name in outputs if name in GAF_OUTPUTS)
    with_rates = bool(gaf_names) or any(name in NEEDS_RATES for name in kinematic)

    def one(layout):
        sol, rates = revolution(
            layout, n_theta, fidelity, with_rates=with_rates, rtol=rtol, max_steps=max_steps
        )
        result = metrics_from(layout, sol, rates, kinematic)
        if gaf_names:
            g = gaf_from_revolution(layout, sol, rates, torque, friction_params, gaf_model, width)
            result.update(gaf_rms=g.rms, gaf_peak=g.peak, gaf_third_order=g.third_order)
        return {name: result[name] for name in outputs}

    return jax.vmap(one)(layouts)


def sweep(
    layouts,
    n_theta=360,
    fidelity="newton",
    outputs=DEFAULT_OUTPUTS,
    chunk_size=None,
    *,
    torque=None,
    friction_params=GREASE_A,
    gaf_model="stroke",
    gaf_width=DEFAULT_STROKE_WIDTH,
    rtol=None,
    max_steps=DEFAULT_MAX_STEPS,
    devices=None,
    progress=None,
):
    """Metrics of many layouts at once.

    Args:
        layouts: a :class:`~tripodjax.Layout` whose fields are 1-D arrays of
            one length N (checked: the same domain as a scalar Layout; the
            error names the field and the index).
        n_theta: angles per revolution (a multiple of 6).
        fidelity: ``"newton"`` or ``"analytic"`` (see :func:`~tripodjax.kinematic_metrics`).
        outputs: names to compute — any :class:`~tripodjax.KinematicMetrics`
            field, and ``"gaf_rms"``, ``"gaf_peak"``, ``"gaf_third_order"`` [N]
            (these need ``torque``). Only these are computed: dψ/dθ, for
            instance, only when ``"irregularity"`` or a GAF output is asked for.
        chunk_size: layouts per compiled call, rounded up to a multiple of the
            device count; bounds the memory. Default: 2^18 solved angles per
            chunk on a CPU (cache-sized: 2184 layouts at n_theta = 360),
            2^22 on an accelerator.
        torque, friction_params, gaf_model, gaf_width: GAF inputs, see
            :func:`~tripodjax.friction.gaf_halfshaft`.
        rtol, max_steps: Newton controls, see :func:`~tripodjax.solve_halfshaft`.
        devices: devices to split each chunk over (default: all visible).
        progress: show a progress bar on standard error; default: only when
            standard error is a terminal and there is more than one chunk.

    Returns:
        dict name → NumPy array of length N. The working dtype is that of the
        layout arrays.
    """
    n = _check_layouts(layouts)
    outputs = _check_outputs(outputs, torque)
    check_fidelity(fidelity)
    period_grid(n_theta, jnp.float32)  # checks n_theta
    if gaf_model not in GAF_MODELS:
        raise ValueError(
            f"gaf_model = {gaf_model!r} is not allowed; allowed: {', '.join(GAF_MODELS)}"
        )
    devices = list(devices) if devices is not None else jax.devices()
    mesh = jax.sharding.Mesh(np.array(devices), ("layouts",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("layouts"))
    backend = devices[0].platform
    default_points = DEFAULT_CHUNK_POINTS.get(backend, DEFAULT_CHUNK_POINTS_ACCELERATOR)
    chunk = chunk_size or max(1, default_points // (n_theta // 3))
    chunk = max(len(devices), math.ceil(min(chunk, max(n, 1)) / len(devices)) * len(devices))
    fields = [np.asarray(getattr(layouts, name)) for name in ("R", "l", "gamma0")]
    n_chunks = math.ceil(n / chunk)
    bar = _Progress(n, sys.stderr.isatty() and n_chunks > 1 if progress is None else progress)
    static = dict(
        n_theta=n_theta,
        fidelity=fidelity,
        outputs=outputs,
        gaf_model=gaf_model,
        max_steps=max_steps,
    )
    pieces = {name: [] for name in outputs}
    pending = None  # one chunk in flight while the next is dispatched (JAX runs asynchronously)

    def collect(done):
        result, count, stop = done
        for name in outputs:
            pieces[name].append(np.asarray(result[name])[:count])
        bar.update(stop)

    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        # Pad the last chunk with copies of its last layout: one compiled shape throughout.
        index = np.minimum(np.arange(start, start + chunk), stop - 1)
        part = Layout(*(jax.device_put(f[index], sharding) for f in fields))
        dispatched = (
            _evaluate_chunk(part, torque, friction_params, gaf_width, rtol, **static),
            stop - start,
            stop,
        )
        if pending is not None:
            collect(pending)
        pending = dispatched
    if pending is not None:
        collect(pending)
    return {name: np.concatenate(pieces[name]) if pieces[name] else np.zeros(0) for name in outputs}
