"""Compiler options of the programs a user waits for: compiled for latency, not throughput.

A program that answers one question once (one layout's metrics and their Jacobian, an
optimiser's solve, a report's numbers) runs for milliseconds and compiles for seconds: its
first answer is its compile time. XLA's CPU backend spends most of that time in LLVM's
optimisation, in its MLIR fusion emitters and, for programs of nested loops, in hoisting loop
invariants; ``LATENCY_BOUND`` turns the three off for such a program only (``jax.jit(...,
compiler_options=...)``, never a global flag). Measured on the README's first example (2-core
AMD EPYC, jaxlib 0.10.2): compile 3.3 s → 1.7 s, each later call 0.5 ms → 1.6 ms; on the
optimiser's model with its Jacobian 3.6 s → 1.5 s, 0.3 ms → 0.6 ms an evaluation. Without the
hoisting, the solve's program compiles in 3.1 s instead of 3.9 s and the chance-constrained
one in 9.1 s instead of 12.9 s (the same module compiled in one process, best of 3), and a
solve runs 0.10 → 0.12 s. Results are the same arithmetic (no fast-math): equal to roundoff.

Throughput programs (a sweep's chunks, Monte Carlo chunks) keep XLA's defaults where they run
long. A small one, which runs for milliseconds, is compiled with ``SMALL_SWEEP_OPTIONS`` (a
sweep of up to ``tripodjax.sweep.SMALL_SWEEP`` solved points), and a library function of arrays
(``latency_bound_at_top_level(..., small_inputs=True)``) with ``LATENCY_BOUND`` where no input
holds more than ``SMALL_INPUT`` elements.
"""

import functools

import jax
import numpy as np

LATENCY_BOUND = {
    # The legacy loop emitters compile a fusion in a fraction of the MLIR emitters' time.
    "xla_cpu_use_fusion_emitters": False,
    # No LLVM optimisation passes (-O0): most of the rest of the compile time.
    "xla_backend_optimization_level": 0,
    # No loop-invariant code motion: on the optimiser's programs, whose model and Jacobian
    # sit in nested while loops (the solve's iterations, the performance-measure steps),
    # XLA's hoisting analysis took a quarter of the compile time and saves no run time.
    "xla_disable_hlo_passes": "while-loop-invariant-code-motion",
}

SMALL_SWEEP_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
"""A small sweep's chunk program: the legacy fusion emitters alone (LLVM still optimises). A
sweep of 1000 layouts at newton (2-core AMD EPYC, fresh processes): first call 1.29 → 0.94 s,
later calls 4.1 → 6.2 ms; with all of ``LATENCY_BOUND``, 0.72 s and 18 ms, and two programs of
one computation round apart (a sweep's default outputs and each output alone: 59 of 300 values
an ulp apart; none with these options alone)."""

latency_bound_jit = functools.partial(jax.jit, compiler_options=LATENCY_BOUND)
"""``jax.jit`` with ``LATENCY_BOUND``; takes jax.jit's other arguments (static_argnums, …)."""


SMALL_INPUT = 1 << 16
"""Elements of a program's largest input up to which ``latency_bound_at_top_level(...,
small_inputs=True)`` compiles it with ``LATENCY_BOUND`` (a Hertz sizing, a life, a shaft check
of one design or a few thousand: microseconds to run, tenths of a second to compile; a first
``hertz.capacities`` of one design 0.35–0.45 s → 0.17–0.21 s, a later call 0.5 ms either way,
2-core AMD EPYC, fresh processes)."""


def latency_bound_at_top_level(fun, *, small_inputs=False, **jit_kwargs):
    """``fun`` compiled with ``LATENCY_BOUND`` where it is called at top level, and as a plain
    ``jax.jit`` inside another trace (a user's ``jax.jit``, ``vmap``, ``grad``): JAX takes
    compiler options on a top-level program only, and a nested one is compiled with its caller.

    With ``small_inputs``, only where no input holds more than ``SMALL_INPUT`` elements: a
    function of arrays of any size (a Hertz sizing of a million designs) keeps XLA's defaults
    where it is a throughput program. ``jit_kwargs``: jax.jit's other arguments
    (static_argnames, …)."""
    top_level, nested = latency_bound_jit(fun, **jit_kwargs), jax.jit(fun, **jit_kwargs)

    @functools.wraps(fun)
    def call(*args, **kwargs):
        leaves = jax.tree_util.tree_leaves((args, kwargs))
        if not _at_top_level(leaves):
            return nested(*args, **kwargs)
        if small_inputs and max((np.size(leaf) for leaf in leaves), default=0) > SMALL_INPUT:
            return nested(*args, **kwargs)
        return top_level(*args, **kwargs)

    call.latency_bound, call.plain = top_level, nested  # the two compiled functions
    return call


def _at_top_level(leaves):
    """Whether no trace is active (a library function called with constants inside another
    program is nested too); where JAX does not say, whether no argument is traced."""
    clean = getattr(jax._src.core, "trace_state_clean", None)
    if clean is not None:
        return clean()
    return not any(isinstance(leaf, jax.core.Tracer) for leaf in leaves)
