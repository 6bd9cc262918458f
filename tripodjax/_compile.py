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

Throughput programs (a sweep's chunks, Monte Carlo chunks) keep XLA's defaults.
"""

import functools

import jax

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

latency_bound_jit = functools.partial(jax.jit, compiler_options=LATENCY_BOUND)
"""``jax.jit`` with ``LATENCY_BOUND``; takes jax.jit's other arguments (static_argnums, …)."""


def latency_bound_at_top_level(fun, **jit_kwargs):
    """``fun`` compiled with ``LATENCY_BOUND`` where it is called at top level, and as a plain
    ``jax.jit`` inside another trace (a user's ``jax.jit``, ``vmap``, ``grad``): JAX takes
    compiler options on a top-level program only, and a nested one is compiled with its caller.
    ``jit_kwargs``: jax.jit's other arguments (static_argnames, …)."""
    top_level, nested = latency_bound_jit(fun, **jit_kwargs), jax.jit(fun, **jit_kwargs)

    @functools.wraps(fun)
    def call(*args, **kwargs):
        leaves = jax.tree_util.tree_leaves((args, kwargs))
        traced = any(isinstance(leaf, jax.core.Tracer) for leaf in leaves)
        return (nested if traced else top_level)(*args, **kwargs)

    return call
