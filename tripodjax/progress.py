"""Progress meters for long work (sweeps, the optimiser), pluggable in the manner of Diffrax.

Every long-running function takes ``progress=``: ``None`` (the default: a bar
when standard error is a terminal), ``True``/``False``, or a [`ProgressMeter`][tripodjax.progress.ProgressMeter]
instance. [`TqdmProgressMeter`][tripodjax.progress.TqdmProgressMeter] uses ``tqdm.auto``, so a notebook gets a
notebook bar; [`NoProgressMeter`][tripodjax.progress.NoProgressMeter] prints nothing.
"""

import sys
from typing import Any, Protocol


class ProgressHandle(Protocol):
    """What [`ProgressMeter.start`][tripodjax.progress.ProgressMeter.start] returns."""

    def update(self, n: int = 1, **postfix: Any) -> None: ...

    def close(self) -> None: ...


class ProgressMeter:
    """The interface: ``start`` returns a handle with ``update(n, **postfix)`` and ``close()``."""

    def start(self, total: int, desc: str, unit: str = "it") -> ProgressHandle:
        """Begin a task of ``total`` units named ``desc``; returns its handle."""
        raise NotImplementedError


class _Silent:
    def update(self, n: int = 1, **postfix: Any) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> "_Silent":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class NoProgressMeter(ProgressMeter):
    """Shows nothing."""

    def start(self, total: int, desc: str, unit: str = "it") -> ProgressHandle:
        return _Silent()


class _TqdmHandle(_Silent):
    def __init__(self, bar: Any) -> None:
        self.bar = bar

    def update(self, n: int = 1, **postfix: Any) -> None:
        if postfix:
            self.bar.set_postfix(postfix, refresh=False)
        self.bar.update(n)

    def close(self) -> None:
        self.bar.close()


class TqdmProgressMeter(ProgressMeter):
    """A ``tqdm.auto`` bar on standard error (a widget in a notebook), with rate and ETA."""

    def start(self, total: int, desc: str, unit: str = "it") -> ProgressHandle:
        from tqdm.auto import tqdm

        return _TqdmHandle(
            tqdm(
                total=total, desc=desc, unit=unit, file=sys.stderr, dynamic_ncols=True, leave=False
            )
        )


def resolve(progress: bool | ProgressMeter | None) -> ProgressMeter:
    """The meter for a ``progress=`` argument (None: a bar only when stderr is a terminal)."""
    if isinstance(progress, ProgressMeter):
        return progress
    if progress is None:
        progress = sys.stderr.isatty()
    if not isinstance(progress, bool):
        raise TypeError(
            f"progress = {progress!r} is not allowed; allowed: None, True, False or a ProgressMeter"
        )
    return TqdmProgressMeter() if progress else NoProgressMeter()
