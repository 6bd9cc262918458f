"""Derivatives of one layout's answer from its Jacobian, formed beside the values.

A function of a few numbers (one layout's metrics, its GAF over a revolution) is differentiated
most cheaply to compile by forward mode: one linearisation per floating-point input, batched
(``jax.vmap`` of ``jax.jvp``), in the same program as the values. Reverse mode through the
revolution (``jax.grad`` of the plain function) compiles two larger programs instead, the
forward pass with its residuals and its transpose, and under an eager ``jax.grad`` with XLA's
defaults (JAX takes compiler options on a top-level program only). So these functions are
``jax.custom_jvp`` whose rule answers a tangent with the product of that Jacobian
(``jvp_from_jacobian``): a gradient then transposes the small product alone, and the Jacobian's
program, called at top level, is compiled for latency (``tripodjax._compile``).
"""

import contextlib
import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero

from tripodjax._compile import latency_bound_at_top_level


def differentiable(leaves):
    """The indices of the leaves that are differentiated: the floating-point ones."""
    return [
        i for i, leaf in enumerate(leaves) if jnp.issubdtype(jnp.result_type(leaf), jnp.inexact)
    ]


def values_and_jacobian(fun, *args):
    """``fun(*args)`` and its derivative along each differentiable leaf of ``args`` (scalars):
    a pytree like the values with a leading axis, one entry per such leaf, in leaf order."""
    leaves, tree = jax.tree_util.tree_flatten(args)
    moving = differentiable(leaves)

    def of(*fields):
        changed = list(leaves)
        for i, value in zip(moving, fields, strict=True):
            changed[i] = value
        return fun(*tree.unflatten(changed))

    fields = tuple(leaves[i] for i in moving)
    basis = jnp.eye(len(fields), dtype=jnp.result_type(*fields))

    def along(e):
        return jax.jvp(of, fields, tuple(e[k].astype(f.dtype) for k, f in enumerate(fields)))

    return jax.vmap(along, out_axes=(None, 0))(basis)


# Concrete primals reach a JVP rule under the derivative's own trace (partial evaluation), where
# a jitted call is compiled anew as its "known" part; evaluated outside that trace it is a
# top-level call, which reuses (or compiles for latency) the plain program. JAX has no public
# spelling of this context: without it (another JAX version), the derivative compiles its own
# copy, as before, and the results are the same.
_EVAL_CONTEXT = getattr(jax._src.core, "eval_context", contextlib.nullcontext)


def zero_tangent(value):
    """The zero tangent of a value: zeros, or float0 zeros for an integer (a result code)."""
    if jnp.issubdtype(jnp.result_type(value), jnp.inexact):
        return jnp.zeros_like(value)
    return np.zeros(jnp.shape(value), jax.dtypes.float0)


def plain_jvp(fun, primals, tangents):
    """``jax.jvp(fun, primals, tangents)`` in a rule with symbolic zeros (instantiated)."""
    leaves, tree = jax.tree_util.tree_flatten(primals)
    t_leaves = [
        zero_tangent(leaf) if isinstance(t, SymbolicZero) else t
        for leaf, t in zip(leaves, tree.flatten_up_to(tangents), strict=True)
    ]
    return jax.jvp(fun, primals, tree.unflatten(t_leaves))


def jvp_from_jacobian(fun, with_jacobian, primals, tangents):
    """A ``jax.custom_jvp`` rule (``symbolic_zeros=True``) of ``fun``: ``with_jacobian(*primals)``
    returns its values and their Jacobian as ``values_and_jacobian`` does; the output tangent is
    the Jacobian's product with the primals' tangents (symbolic zeros count as 0). Array leaves,
    outside the public API, where a leaf's tangent is not one number: ``fun``'s plain JVP."""
    leaves, tree = jax.tree_util.tree_flatten(primals)
    if any(jnp.ndim(leaf) for leaf in leaves):
        return plain_jvp(fun, primals, tangents)
    if any(isinstance(leaf, jax.core.Tracer) for leaf in leaves):
        out, columns = with_jacobian(*primals)
    else:  # an eager derivative: the top-level program, not a partially evaluated copy
        with _EVAL_CONTEXT():
            out, columns = with_jacobian(*primals)
    moving = differentiable(leaves)
    if not moving:
        return out, jax.tree_util.tree_map(zero_tangent, out)
    t_leaves = tree.flatten_up_to(tangents)
    dtype = jnp.result_type(*(leaves[i] for i in moving))
    weights = jnp.stack(
        [
            jnp.zeros((), dtype) if isinstance(t_leaves[i], SymbolicZero) else t_leaves[i]
            for i in moving
        ]
    ).astype(dtype)

    def combine(value, column):
        if not jnp.issubdtype(value.dtype, jnp.inexact):
            return zero_tangent(value)
        return jnp.tensordot(weights.astype(column.dtype), column, axes=1)

    return out, jax.tree_util.tree_map(combine, out, columns)


def differentiated_by_jacobian(fun, static_argnames):
    """``fun(*args, **static)`` (``static_argnames`` by keyword) as a program compiled for
    latency at top level, whose derivatives come from a second one of its values and Jacobian
    w.r.t. the floating-point leaves of ``args`` (``jvp_from_jacobian``). ``.plain`` and
    ``.with_jacobian``: the two programs."""
    plain = latency_bound_at_top_level(fun, static_argnames=static_argnames)

    def both(*args, **static):
        return values_and_jacobian(functools.partial(fun, **static), *args)

    both.__name__ = both.__qualname__ = f"{fun.__name__}_and_jacobian"  # the program's name
    with_jacobian = latency_bound_at_top_level(both, static_argnames=static_argnames)

    @functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
    def with_rule(static, *args):
        return plain(*args, **dict(static))

    def rule(static, primals, tangents):
        return jvp_from_jacobian(
            functools.partial(fun, **dict(static)),
            functools.partial(with_jacobian, **dict(static)),
            primals,
            tangents,
        )

    with_rule.defjvp(rule, symbolic_zeros=True)

    @functools.wraps(fun)
    def call(*args, **static):
        return with_rule(tuple(sorted(static.items())), *args)

    call.plain, call.with_jacobian = plain, with_jacobian
    return call
