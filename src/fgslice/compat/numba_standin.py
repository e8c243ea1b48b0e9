"""What an OpenVCAD 3 script imports as ``numba``: ``cfunc`` and ``types``, nothing compiled.

OpenVCAD 3 takes Python attribute functions only as Numba ``@cfunc`` objects
(``@cfunc(types.float64(types.float64, types.float64, types.float64, types.float64))``).
fgslice does not compile them: ``cfunc(signature)`` returns a decorator that keeps the
Python function in a :class:`CFunc` (still callable with numbers, as the compiled function
is), and :mod:`fgslice.compat.pyvcad_v3` evaluates it on whole numpy arrays, or point by
point when the function only takes numbers (``if t < 0.0:``, ``max(a, b)``). The script
runner (:mod:`fgslice.compat.script`) offers this module as ``numba`` while a design
script runs, whether or not Numba is installed, so a script gives the same design
everywhere. Other Numba names fail with their name.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

from fgslice.errors import DesignError

_HINT = "fgslice offers numba.cfunc and numba.types for OpenVCAD attribute functions only"


class _Type:
    """A Numba scalar type; calling it with argument types makes a signature."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __call__(self, *args: "_Type") -> "Signature":
        return Signature(self, args)

    def __repr__(self) -> str:
        return self.name


class Signature:
    """``types.float64(types.float64, ...)``: a return type and argument types."""

    def __init__(self, result: _Type, args: tuple) -> None:
        self.result, self.args = result, tuple(args)

    def __repr__(self) -> str:
        return f"{self.result!r}({', '.join(map(repr, self.args))})"


class _Types:
    """``numba.types``: the scalar types OpenVCAD's signatures use."""

    float64 = _Type("float64")
    float32 = _Type("float32")
    int64 = _Type("int64")
    int32 = _Type("int32")
    boolean = _Type("boolean")

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise DesignError(f"numba.types.{name} is not supported by fgslice", hint=_HINT)


types = _Types()
float64 = types.float64


class CFunc:
    """A function decorated with ``@cfunc(signature)``: the Python function, its signature
    and its argument count. Calling it calls the Python function."""

    def __init__(self, function: Callable, signature: Signature | str | None) -> None:
        if not callable(function):
            raise DesignError(f"numba.cfunc decorates a function, got {function!r}", hint=_HINT)
        self.py_func = function
        self.signature = signature
        self.__name__ = getattr(function, "__name__", "cfunc")
        parameters = inspect.signature(function).parameters.values()
        self.arity = sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in parameters)
        if isinstance(signature, Signature) and len(signature.args) != self.arity:
            raise DesignError(
                f"numba.cfunc: '{self.__name__}' takes {self.arity} arguments but its signature {signature!r} "
                f"has {len(signature.args)}")

    def __call__(self, *args):
        return self.py_func(*args)

    def __repr__(self) -> str:
        return f"<cfunc {self.__name__} {self.signature!r}>"


def cfunc(signature=None, **options) -> Callable[[Callable], CFunc]:
    """``@cfunc(signature)``: keep the decorated Python function as a :class:`CFunc`."""
    if callable(signature) and not isinstance(signature, (_Type, Signature)):
        raise DesignError("numba.cfunc needs a signature: @cfunc(types.float64(types.float64, ...))", hint=_HINT)

    def decorate(function: Callable) -> CFunc:
        return CFunc(function, signature)

    return decorate


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    raise DesignError(f"numba.{name} is not supported by fgslice", hint=_HINT)
