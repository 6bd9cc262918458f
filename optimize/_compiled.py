"""Calling the optimiser's compiled functions, optionally through a cache of executables.

The library calls its jit-compiled functions directly. The ``optimize-joint``
command wraps its work in [`executable_cache`][tripodjax.optimize._compiled.executable_cache]:
each function is then compiled once per spec structure, argument shapes, versions,
device and package source, and its executable kept (``jax.experimental.serialize_executable``);
a later process loads it and neither traces, lowers nor compiles (where JAX's persistent
compilation cache, keyed on the lowered program, would have it trace and lower each
function again: 1.5 s of a warm run, measured). Every optimiser program runs for
milliseconds a call and is compiled for latency (``tripodjax._compile.LATENCY_BOUND``),
cached or not. An entry holds its own key and is checked against the call's arguments
when called; any mismatch removes it and compiles again. The folder holds at most
``MAX_CACHE_BYTES``: the least recently used entries (by their files' modification times, set
when an entry is loaded) go first.
"""

import contextlib
import contextvars
import functools
import hashlib
import os
import pathlib
import pickle
import tempfile
import threading

import jax
import jaxlib.version
from jax.experimental import serialize_executable

from tripodjax._compile import latency_bound_jit

__all__ = ["batch_rows", "call", "executable_cache", "latency_bound_jit", "rows_per_call"]

_CACHE = contextvars.ContextVar("tripodjax_executable_cache", default=None)
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
    """``jitted(static, *args)``, through the active executable cache if there is one."""
    cache = _CACHE.get()
    if cache is None:
        return jitted(static, *args)
    return cache.call(jitted, static, *args)


@contextlib.contextmanager
def executable_cache(directory):
    """Within the block, compiled calls go through executables kept in ``directory``."""
    token = _CACHE.set(_ExecutableCache(directory))
    try:
        yield
    finally:
        _CACHE.reset(token)


@functools.cache
def _source_digest():
    """A digest of the package's own source: a changed file never loads a stale executable."""
    import tripodjax

    digest = hashlib.sha256()
    roots = [pathlib.Path(tripodjax.__file__).parent, pathlib.Path(__file__).parent]
    for root in roots:
        for path in sorted(root.glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


class _ExecutableCache:
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
                jaxlib.version.__version__,
                jax.config.jax_enable_x64,
                jax.default_backend(),
                [d.device_kind for d in jax.local_devices()],
                _source_digest(),
            )
        )
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    def call(self, jitted, static, *args):
        key = self._key(jitted, static, args)
        compiled = self.loaded.get(key)
        if compiled is None:
            compiled = self._load(key)
            if compiled is not None:
                try:
                    out = compiled(*args)
                except TypeError:  # an entry that passed the checks and still does not fit
                    self._remove(key)
                else:
                    self.loaded[key] = compiled
                    return out
            self.loaded[key] = compiled = self._compile(key, jitted, static, args)
        return compiled(*args)

    def _path(self, key):
        return self.directory / f"{key}.jaxexec"

    def _remove(self, key):
        with contextlib.suppress(OSError):
            self._path(key).unlink()

    def _load(self, key):
        """The executable under ``key``, loaded, or None (absent, another key's, corrupt).

        An entry holds its own key, then the pickled input and output trees and the
        serialized executable. A file of another key (copied, swapped or truncated) or one
        that does not load is removed (compiled again by the caller). Unpickling runs code
        named by the file, as loading an executable runs its machine code: the cache is
        trusted as the package's own files are (the user's own folder).
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
            in_tree, out_tree, executable = pickle.loads(data[len(header) :])
            _linear_algebra_ready()
            loaded = serialize_executable.deserialize_and_load(executable, in_tree, out_tree)
            with contextlib.suppress(OSError):
                os.utime(path)  # in use: the last entry `_prune` removes
            return loaded
        except Exception:  # corrupt, from another jaxlib, another key's
            self._remove(key)
            return None

    def _compile(self, key, jitted, static, args):
        """``jitted`` compiled for ``static`` and the arguments' shapes, and kept under ``key``."""
        _watch_persistent_cache_hits()
        _HITS.count = 0
        compiled = jitted.lower(static, *args).compile()
        if _HITS.count:  # JAX's persistent cache answered: its executable does not serialize
            return compiled  # whole again (kernels missing when loaded, seen): not kept
        try:
            executable, in_tree, out_tree = serialize_executable.serialize(compiled)
            data = pickle.dumps((in_tree, out_tree, executable))
        except Exception:  # an executable that cannot be serialized here: not kept
            return compiled
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".entry.", dir=self.directory)
            with os.fdopen(fd, "wb") as f:
                f.write(_header(key))
                f.write(data)
            os.replace(tmp, self._path(key))
            _prune(self.directory, MAX_CACHE_BYTES)
        except OSError:
            pass  # a read-only cache only costs time
        return compiled


MAX_CACHE_BYTES = 2**30
"""The cache's size [bytes] beyond which writing an entry removes the least recently used ones
(an entry is some 0.1–6 MB; a new version or package source adds entries of new keys)."""


def _prune(directory, limit):
    """Remove the least recently used entries of ``directory`` until they hold ≤ ``limit`` bytes."""
    entries = []
    for path in directory.glob("*.jaxexec"):
        with contextlib.suppress(OSError):  # another process may remove it meanwhile
            stat = path.stat()
            entries.append((stat.st_mtime, stat.st_size, path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= limit:
            break
        with contextlib.suppress(OSError):
            path.unlink()
        total -= size


_HITS = threading.local()  # persistent-cache hits of JAX in this thread, since last reset


@functools.cache
def _watch_persistent_cache_hits():
    """Count JAX's persistent-cache hits per thread (a listener, registered once).

    An executable that JAX's persistent cache returned serializes without its kernels (jaxlib
    0.10.2: "Function ... not found" when the entry is loaded and called); ``optimize-joint``
    turns that cache off, a process that keeps it on (tests, a user's setting) stores none.
    """

    def count(event, **_):
        if event == "/jax/compilation_cache/cache_hits":
            _HITS.count = getattr(_HITS, "count", 0) + 1

    jax.monitoring.register_event_listener(count)


@functools.cache
def _linear_algebra_ready():
    """Load the LAPACK kernels an executable may call on the CPU (LU factorisations).

    JAX loads them when it lowers a linear-algebra operation; a process that only loads
    executables lowers none, and their kernels would be called unloaded (a segmentation
    fault, seen). JAX's own function where it has it, else a small LU lowered (not compiled).
    """
    initialize = getattr(getattr(jax._src.lax, "linalg", None), "initialize_lapack", None)
    if initialize is not None:
        initialize()
    else:
        jax.jit(jax.lax.linalg.lu).lower(jax.numpy.eye(2))


def _header(key):
    """What an entry starts with: the format and its own key (checked when it is loaded)."""
    return f"tripodjax-executable 1 {key}\n".encode()
