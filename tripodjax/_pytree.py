"""Frozen dataclasses registered as JAX pytrees (every field is a leaf)."""

import dataclasses

import jax


def pytree_dataclass(cls):
    """Make ``cls`` a frozen dataclass whose fields are all pytree leaves.

    ``jax.tree_util`` rebuilds instances through ``__init__`` (so
    ``__post_init__`` also runs on tracers and placeholders; validation must
    skip anything that is not a plain Python number).
    """
    cls = dataclasses.dataclass(frozen=True)(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    return jax.tree_util.register_dataclass(cls, data_fields=names, meta_fields=[])
