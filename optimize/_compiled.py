"""Calling the optimiser's compiled functions, optionally through serialized exports.

The library calls its jit-compiled functions directly. The ``optimize-joint``
command wraps its work in [`export_cache`][tripodjax.optimize._compiled.export_cache]:
each function is then exported once (``jax.export``) per spec structure, argument
shapes, versions and package source, and a later process loads that export instead
of tracing the Python again; with JAX's persistent compilation cache beside it, a
warm command neither traces nor compiles.
"""

import contextlib
import contextvars
import functools
import hashlib
import os
import pathlib
import tempfile

import jax

_CACHE = contextvars.ContextVar("tripodjax_export_cache", default=None)
_ROWS = contextvars.ContextVar("tripodjax_batch_rows", default=None)


def batch_rows():
    """Rows per call of the solve program when it evaluates points; None outside [`rows_per_call`][tripodjax.optimize._compiled.rows_per_call]."""
    return _ROWS.get()


@contextlib.contextmanager
def rows_per_call(rows):
    """Within the block, point evaluations use the solve program at ``rows`` rows per call.

    Set it to the batch of a solve that ran (or will run) in the same process, so
    that the catalogue, the landscape and the sensitivities reuse its compiled program.
    """
    token = _ROWS.set(int(rows))
    try:
        yield
    finally:
        _ROWS.reset(token)


def call(jitted, static, *args):
    """``jitted(static, *args)``, through the active export cache if there is one."""
    cache = _CACHE.get()
    if cache is None:
        return jitted(static, *args)
    return cache.call(jitted, static, *args)


@contextlib.contextmanager
def export_cache(directory):
    """Within the block, compiled calls go through exports kept in ``directory``."""
    token = _CACHE.set(_ExportCache(directory))
    try:
        yield
    finally:
        _CACHE.reset(token)


@functools.cache
def _source_digest():
    """A digest of the package's own source: a changed file never loads a stale export."""
    import tripodjax

    digest = hashlib.sha256()
    roots = [pathlib.Path(tripodjax.__file__).parent, pathlib.Path(__file__).parent]
    for root in roots:
        for path in sorted(root.glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


class _ExportCache:
    def __init__(self, directory):
        self.directory = pathlib.Path(directory)
        self.loaded = {}

    def _key(self, jitted, static, args):
        leaves, treedef = jax.tree_util.tree_flatten(args)
        signature = [(tuple(jax.numpy.shape(a)), str(jax.numpy.result_type(a))) for a in leaves]
        text = repr(
            (
                getattr(jitted, "__qualname__", repr(jitted)),
                static,
                str(treedef),
                signature,
                jax.__version__,
                jax.config.jax_enable_x64,
                jax.default_backend(),
                _source_digest(),
            )
        )
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    def call(self, jitted, static, *args):
        key = self._key(jitted, static, args)
        exported = self.loaded.get(key)
        if exported is None:
            exported = self._load(key) or self._export(key, jitted, static, args)
            self.loaded[key] = exported
        if exported is False:  # this function cannot be exported here: call it directly
            return jitted(static, *args)
        return exported.call(*args)

    def _load(self, key):
        try:
            data = (self.directory / f"{key}.jaxexport").read_bytes()
            return jax.export.deserialize(bytearray(data))
        except Exception:  # absent, unreadable, corrupt or from another jaxlib: export again
            return None

    def _export(self, key, jitted, static, args):
        try:
            exported = jax.export.export(jitted)(static, *args)
            data = exported.serialize()
        except Exception:  # e.g. no flatbuffers package: call the function directly
            return False
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".export.", dir=self.directory)
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, self.directory / f"{key}.jaxexport")
        except OSError:
            pass  # a read-only cache only costs time
        return exported
