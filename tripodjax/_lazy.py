"""Packages whose attributes are imported on first use (PEP 562).

Importing a submodule binds it to its package under its own name. Where a package's
attribute of that name is a function of the submodule (``tripodjax.sweep``,
``tripodjax.optimize.reliability``), the binding would replace the function by the module;
[`keep_functions`][tripodjax._lazy.keep_functions] keeps the function.
"""

import sys
import types
import typing


class _Package(types.ModuleType):
    _functions: typing.ClassVar[frozenset[str]] = frozenset()

    def __setattr__(self, name: str, value: typing.Any) -> None:
        if name in self._functions and isinstance(value, types.ModuleType):
            value = getattr(value, name)  # the function of that name, as ``from … import`` made it
        super().__setattr__(name, value)


def keep_functions(package: str, names: typing.Iterable[str]) -> None:
    """Keep ``package.<name>`` the function ``<name>`` when the submodule of that name loads."""
    kind = type("Package", (_Package,), {"_functions": frozenset(names)})
    sys.modules[package].__class__ = kind
