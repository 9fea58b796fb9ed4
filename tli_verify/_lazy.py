"""Lazy public namespaces: a package's names load their modules when first used.

``import tli_verify`` and ``import tli_verify.testing`` stay cheap (Spot, CUDD, cvxpy,
hypothesis and MuJoCo load only when a name that needs them is used).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping
from typing import Any

__all__ = ["lazy_namespace"]


def lazy_namespace(package: str, names: Mapping[str, str], namespace: MutableMapping[str, Any],
                   public: list[str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of a lazy package.

    Parameters
    ----------
    package : str
        The package's name (for the error message).
    names : mapping of str to str
        Public name -> the module that defines it.
    namespace : mutable mapping
        The package's ``globals()``: a name is cached there once loaded.
    public : list of str
        The package's ``__all__``.

    Returns
    -------
    (callable, callable)
        ``__getattr__(name)`` and ``__dir__()``.
    """

    def __getattr__(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(public))

    return __getattr__, __dir__
