"""The public surface (``tli_verify.__all__``) is typed and keyword-driven (issue 33).

* no ``Any`` in a public signature, except a JSON document (``dict[str, Any]``, a model's
  ``source`` mapping: the parsed content of a certificate, evidence, automaton or provenance
  record, whose schema is published);
* options (parameters with defaults) are keyword-only after the first two parameters;
* the error families a user catches are exported, each input error also the builtin it means.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterator

import pytest

import tli_verify as tli

JSON_DOCS = ("dict[str, Any]", "Mapping[str, Any]")


def _without_json(annotation: str) -> str:
    for doc in JSON_DOCS:
        annotation = annotation.replace(doc, "")
    return annotation


def _public_callables() -> Iterator[tuple[str, Callable[..., object]]]:
    for name in tli.__all__:
        obj = getattr(tli, name)
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj) and not issubclass(obj, BaseException):
            for member, fn in vars(obj).items():
                if inspect.isfunction(fn) and (not member.startswith("_") or member == "__init__"):
                    yield f"{name}.{member}", fn


@pytest.mark.parametrize(("name", "fn"), list(_public_callables()),
                         ids=[n for n, _ in _public_callables()])
def test_no_any_in_a_public_signature(name: str, fn: Callable[..., object]) -> None:
    bad = {k: v for k, v in fn.__annotations__.items()
           if "Any" in _without_json(str(v))}
    assert not bad, f"{name}: Any in {bad}"


@pytest.mark.parametrize(("name", "fn"), list(_public_callables()),
                         ids=[n for n, _ in _public_callables()])
def test_options_are_keyword_only(name: str, fn: Callable[..., object]) -> None:
    """After the first two parameters, an option (a parameter with a default) is keyword-only;
    the data a call works on (parameters without defaults) may come positionally. Frozen
    dataclasses' fields excepted."""
    if name.endswith(".__init__"):
        return
    params = [p for p in inspect.signature(fn).parameters.values() if p.name != "self"][2:]
    positional_options = [p.name for p in params if p.default is not p.empty
                          and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    assert not positional_options, f"{name}: options taken positionally: {positional_options}"


def test_the_error_families_are_exported() -> None:
    assert issubclass(tli.InputError, tli.TliError) and issubclass(tli.InputError, ValueError)
    assert issubclass(tli.OutputError, tli.InputError)
    assert issubclass(tli.CheckFailed, tli.TliError)
    for family in (tli.SpecError, tli.TaskError, tli.DemoError, tli.ModelError,
                   tli.CertificateError, tli.GateError):
        assert issubclass(family, tli.TliError)
    with pytest.raises(tli.InputError, match="steps"):
        tli.open_project(tli.find_task("scoop").spec_path).run(steps=0)
