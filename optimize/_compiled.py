"""Calling the optimiser's compiled functions, optionally through serialized exports.

The library calls its jit-compiled functions directly. The ``optimize-joint``
command wraps its work in [`export_cache`][tripodjax.optimize._compiled.export_cache]:
each function is then exported once (``jax.export``) per spec structure, argument
shapes, versions and package source, and a later process loads that export instead
of tracing the Python again; with JAX's persistent compilation cache beside it, a
warm command neither traces nor compiles. Every optimiser program runs for milliseconds a
call and is compiled for latency (``tripodjax._compile.LATENCY_BOUND``), exported or not. An entry holds its own key and is checked
against the call's arguments when loaded; any mismatch removes it and exports again.
"""

import contextlib
import contextvars
import functools
import hashlib
import os
import pathlib
import tempfile

import jax

from tripodjax._compile import latency_bound_jit

__all__ = ["batch_rows", "call", "export_cache", "latency_bound_jit", "rows_per_call"]

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
        from_disk = False
        if exported is None:
            exported = self._load(key, args)
            from_disk = exported is not None
            if not from_disk:
                exported = self._export(key, jitted, static, args)
            self.loaded[key] = exported
        if exported is False:  # this function cannot be exported here: call it directly
            return jitted(static, *args)
        if not from_disk:
            return exported(*args)
        try:
            return exported(*args)
        except Exception:  # an entry that passed the checks and still does not fit: replace it
            self._remove(key)
            self.loaded[key] = exported = self._export(key, jitted, static, args)
            return jitted(static, *args) if exported is False else exported(*args)

    def _path(self, key):
        return self.directory / f"{key}.jaxexport"

    def _remove(self, key):
        with contextlib.suppress(OSError):
            self._path(key).unlink()

    def _load(self, key, args):
        """The entry under ``key`` if it is this key's export for these arguments, else None.

        An entry holds its own key before the serialized export; a file of another key
        (copied, swapped or truncated), one that does not deserialize, or one whose input
        tree and shapes are not those of ``args`` is removed (exported again by the caller).
        """
        path = self._path(key)
        try:
            data = path.read_bytes()
        except OSError:  # absent or unreadable
            return None
        header = _header(key)
        try:
            if not data.startswith(header):
                raise ValueError("the entry is not this key's")
            exported = jax.export.deserialize(bytearray(data[len(header) :]))
            leaves, treedef = jax.tree_util.tree_flatten((args, {}))
            signature = [(tuple(jax.numpy.shape(a)), jax.numpy.result_type(a)) for a in leaves]
            stored = [(tuple(a.shape), a.dtype) for a in exported.in_avals]
            if exported.in_tree != treedef or stored != signature:
                raise ValueError("the entry takes other arguments")
        except Exception:  # corrupt, from another jaxlib, another key's, other arguments
            self._remove(key)
            return None
        return _runner(exported)

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
                f.write(_header(key))
                f.write(data)
            os.replace(tmp, self._path(key))
        except OSError:
            pass  # a read-only cache only costs time
        return _runner(exported)


def _runner(exported):
    """A function calling ``exported``, compiled as the function it was exported from was."""
    return latency_bound_jit(exported.call)


def _header(key):
    """What an entry starts with: the format and its own key (checked when it is loaded)."""
    return f"tripodjax-export 1 {key}\n".encode()
