"""Spot, imported once without its SWIG bindings' DeprecationWarnings.

``import spot`` warns "builtin type SwigPyPacked has no __module__ attribute" (and for
``SwigPyObject``, ``swigvarlink``) under Python 3.12+, and under 3.11 when warnings are shown
or are errors: a third party's warnings, which a user's pytest run would report as theirs. Every
module of tli-verify that needs Spot imports it from here (inside a function: Spot loads only
when used).
"""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message=r"builtin type (SwigPy\w*|swigvarlink) has no "
                            "__module__ attribute", category=DeprecationWarning)
    import spot

__all__ = ["spot"]
