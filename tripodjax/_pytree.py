"""Frozen dataclasses registered as JAX pytrees (every field is a leaf)."""

import dataclasses
import typing

import jax

_T = typing.TypeVar("_T")


@typing.dataclass_transform(frozen_default=True)
def pytree_dataclass(cls: type[_T]) -> type[_T]:
    """Make ``cls`` a frozen dataclass whose fields are all pytree leaves.

    ``jax.tree_util`` rebuilds instances through ``__init__`` (so
    ``__post_init__`` also runs on tracers and placeholders; validation must
    skip anything that is not a plain Python number).
    """
    cls = dataclasses.dataclass(frozen=True)(cls)
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]  # a dataclass now
    return jax.tree_util.register_dataclass(cls, data_fields=names, meta_fields=[])
