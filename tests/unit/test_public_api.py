"""The public namespace: what ``tli_verify.__all__`` promises, lazily, documented, and errors
that are the builtins they mean (exit codes are the CLI's business)."""

from __future__ import annotations

import errno
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

import tli_verify
from tli_verify.errors import InputError, TliError, bad_input, missing


def test_all_is_the_lazy_table_and_every_name_resolves() -> None:
    from tli_verify import _NAMES

    assert sorted(tli_verify.__all__) == sorted(_NAMES)
    assert tli_verify.__all__ == sorted(tli_verify.__all__)
    assert 25 <= len(tli_verify.__all__) <= 50
    for name in tli_verify.__all__:
        value = getattr(tli_verify, name)
        assert value is not None, name
        if name != "__version__":
            # the object lives where the table says (no copies, one definition)
            assert value.__module__ == _NAMES[name], (name, value.__module__)
    assert set(tli_verify.__all__) <= set(dir(tli_verify))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        tli_verify.nope  # noqa: B018


def test_import_loads_no_solver() -> None:
    code = ("import sys, tli_verify; tli_verify.__version__; "
            "print(sorted(m for m in ('cvxpy', 'spot', 'dd', 'mujoco', 'hypothesis', 'numpy') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60).stdout.strip()
    assert out == "[]"


_SECTION = re.compile(r"^(?P<indent>[ ]*)(Parameters|Attributes)\n(?P=indent)-{4,}\n",
                      re.MULTILINE)


def documented_names(doc: str) -> set[str]:
    """Names a numpydoc ``Parameters`` (or, for a dataclass, ``Attributes``) section lists.

    ``a, b : type`` lists two; ``**options`` lists ``options``.
    """
    doc = inspect.cleandoc(doc)
    names: set[str] = set()
    for m in _SECTION.finditer(doc):
        body = doc[m.end():]
        for line in body.splitlines():
            if not line.strip():
                continue
            if line.startswith(" "):  # a description line
                continue
            if re.match(r"^-{3,}$", line) or (line and not line.startswith(" ") and
                                              re.match(r"^[A-Z][a-z]+( [A-Za-z]+)?$", line)):
                break  # the next section
            head = line.split(" : ", 1)[0]
            for part in head.split(","):
                names.add(part.strip().lstrip("*"))
    return names


def test_the_section_parser_reads_numpydoc() -> None:
    doc = """Summary.

    Parameters
    ----------
    a, b : int
        Two.
    c
    **options
        More.

    Returns
    -------
    int
    """
    assert documented_names(doc) == {"a", "b", "c", "options"}


def _public_callables() -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    for name in tli_verify.__all__:
        value = getattr(tli_verify, name)
        if inspect.isclass(value) and issubclass(value, BaseException):
            continue  # errors take a message
        if inspect.isfunction(value) or inspect.isclass(value):
            out.append((name, value))
        if inspect.isclass(value) and value.__module__ == "tli_verify.api":
            for attr, member in vars(value).items():
                if inspect.isfunction(member) and not attr.startswith("_"):
                    out.append((f"{name}.{attr}", member))
    return out


@pytest.mark.parametrize(("name", "obj"), _public_callables(),
                         ids=[name for name, _ in _public_callables()])
def test_every_public_parameter_is_documented(name: str, obj: object) -> None:
    target = obj.__init__ if inspect.isclass(obj) else obj  # type: ignore[misc]
    try:
        params = [p for p in inspect.signature(target).parameters.values()
                  if p.name not in ("self", "cls") and not p.name.startswith("_")]
    except (TypeError, ValueError):  # pragma: no cover - builtins without signatures
        pytest.skip(f"{name}: no signature")
    doc = inspect.getdoc(obj) or ""
    assert doc.strip(), f"{name}: no docstring"
    if not params:
        return
    listed = documented_names(doc)
    if inspect.isclass(obj) and obj.__init__.__doc__:  # type: ignore[misc]
        listed |= documented_names(obj.__init__.__doc__)  # type: ignore[misc]
    undocumented = [p.name for p in params if p.name not in listed]
    assert not undocumented, f"{name}: parameters not in its docstring: {undocumented}"


def test_input_errors_are_value_errors_and_missing_files_file_not_found(
        tmp_path: Path) -> None:
    for cls in (tli_verify.SpecError, tli_verify.TaskError, tli_verify.DemoError,
                tli_verify.ModelError):
        assert issubclass(cls, InputError) and issubclass(cls, ValueError)
        assert issubclass(cls, TliError)
    # a verdict is not bad input
    assert not issubclass(tli_verify.CertificateError, ValueError)
    assert not issubclass(tli_verify.GateError, ValueError)
    e = bad_input(tli_verify.CertificateError, "malformed")
    assert isinstance(e, tli_verify.CertificateError) and isinstance(e, ValueError)
    gone = tmp_path / "gone.toml"
    e2 = missing(tli_verify.SpecError, f"{gone}: not found", gone)
    assert isinstance(e2, FileNotFoundError) and e2.errno == errno.ENOENT
    assert e2.filename == str(gone) and str(e2) == f"{gone}: not found"
    # through the public functions, as a user meets them
    with pytest.raises(FileNotFoundError) as info:
        tli_verify.load_spec(gone)
    assert isinstance(info.value, tli_verify.SpecError)
    with pytest.raises(FileNotFoundError):
        tli_verify.load_model(tmp_path / "gone.model.json")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\ninputs = [\n")
    with pytest.raises(ValueError, match=r"bad\.toml"):
        tli_verify.load_spec(bad)
    # errors carry no exit codes: the CLI maps them
    assert not hasattr(tli_verify.SpecError("x"), "exit_code")


def test_errors_pickle_across_processes() -> None:
    import pickle

    e = bad_input(tli_verify.CertificateError, "m")
    back = pickle.loads(pickle.dumps(e))
    assert type(back) is type(e) and str(back) == "m"
    f = missing(tli_verify.ModelError, "gone", "/x")
    back2 = pickle.loads(pickle.dumps(f))
    assert isinstance(back2, FileNotFoundError) and isinstance(back2, tli_verify.ModelError)


def test_the_cli_maps_errors_to_exit_codes() -> None:
    from tli_verify.commands import exit_code
    from tli_verify.errors import CheckFailed

    assert exit_code(tli_verify.SpecError("x")) == 2
    assert exit_code(bad_input(tli_verify.CertificateError, "x")) == 2
    assert exit_code(tli_verify.CertificateError("x")) == 1
    assert issubclass(tli_verify.CertificateError, CheckFailed)
    assert exit_code(FileNotFoundError("x")) == 2
