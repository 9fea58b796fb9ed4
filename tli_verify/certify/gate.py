"""The deployment gate (``tli gate [DIR]``): nothing uncertified or tampered with ships.

The gate re-verifies; it never trusts a stored verdict (``docs/design.md``, "Certificates are
re-checked, never trusted"). Under a project directory ``DIR`` it requires that

1. every certificate under ``DIR/certificates/`` re-checks exactly
   (:func:`tli_verify.certify.certificate.check_certificate`): digest, model and spec hashes,
   the model's ``P``, the recorded eigenvalues and the rational Lyapunov check;
2. every model under ``DIR/models/`` is covered by at least one such valid certificate;
3. every spec under ``DIR/specs/`` re-checks with :func:`tli_verify.logic.check.check_spec_file`
   and gets the verdict it declares (``expect``; realizable specs must also be well-separated).

Any failure blocks.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tli_verify.certify.certificate import check_certificate
from tli_verify.errors import GateError, TliError

__all__ = ["GateItem", "GateReport", "run_gate"]


@dataclass(frozen=True, slots=True)
class GateItem:
    """One thing the gate checked.

    Attributes
    ----------
    kind : str
        ``"certificate"``, ``"model"`` or ``"spec"``.
    path : str
        The file.
    ok : bool
    message : str
        What passed, or what blocks.
    """

    kind: str
    path: str
    ok: bool
    message: str

    def to_json(self) -> dict[str, Any]:
        """One ``--json`` record."""
        return {"kind": self.kind, "path": self.path, "ok": self.ok, "message": self.message}


@dataclass(frozen=True, slots=True)
class GateReport:
    """Everything the gate checked.

    Attributes
    ----------
    root : str
    items : tuple of GateItem
    """

    root: str
    items: tuple[GateItem, ...]

    @property
    def ok(self) -> bool:
        """True iff nothing blocks."""
        return all(i.ok for i in self.items)

    @property
    def blockers(self) -> tuple[GateItem, ...]:
        """The failing items."""
        return tuple(i for i in self.items if not i.ok)

    def count(self, kind: str) -> int:
        """Number of items of one kind."""
        return sum(1 for i in self.items if i.kind == kind)


def _files(directory: Path, pattern: str) -> list[Path]:
    return sorted(p for p in directory.rglob(pattern) if p.is_file()) if directory.is_dir() \
        else []


def _default_spec_checker() -> Callable[[Path], Any]:
    from tli_verify.logic.check import check_spec_file

    return check_spec_file


def _spec_item(path: Path, shown: str, checker: Callable[[Path], Any]) -> GateItem:
    try:
        result = checker(path)
    except TliError as exc:
        return GateItem("spec", shown, False, f"does not load: {exc}")
    realizable = bool(result.realizable)
    expected = bool(result.expected_realizable)
    as_expected = bool(getattr(result, "as_expected", realizable == expected))
    verdict = "realizable" if realizable else "unrealizable"
    if as_expected:
        return GateItem("spec", shown, True, f"{verdict}, as the spec declares")
    if realizable != expected:
        return GateItem("spec", shown, False, f"{verdict}, but the spec declares "
                        f"{'realizable' if expected else 'unrealizable'}")
    return GateItem("spec", shown, False, f"{verdict} but not well-separated: it may be won "
                    "vacuously (declare expect = \"not-well-separated\" if intended)")


def run_gate(root: str | os.PathLike[str] = ".", *,
             spec_checker: Callable[[Path], Any] | None = None) -> GateReport:
    """Run the deployment gate on a project directory.

    Parameters
    ----------
    root : path-like, optional
        Project directory holding ``certificates/``, ``models/`` and ``specs/``.
    spec_checker : callable, optional
        ``path -> result`` with ``.realizable`` and ``.expected_realizable`` (default:
        :func:`tli_verify.logic.check.check_spec_file`).

    Returns
    -------
    GateReport

    Raises
    ------
    GateError
        ``root`` is not a directory (exit 2).
    """
    base = Path(root)
    if not base.is_dir():
        raise GateError(f"{base}: not a directory", exit_code=2)

    def shown(p: Path) -> str:
        try:
            return p.resolve().relative_to(base.resolve()).as_posix()
        except ValueError:
            return str(p)

    items: list[GateItem] = []
    covered: set[Path] = set()
    for cert in _files(base / "certificates", "*.json"):
        check = check_certificate(cert)
        if check.ok:
            model = Path(check.model_path or "").resolve()
            covered.add(model)
            items.append(GateItem("certificate", shown(cert), True,
                                  f"re-checked exactly; covers {shown(model)} "
                                  f"({len(check.passed)} checks)"))
        else:
            items.append(GateItem("certificate", shown(cert), False,
                                  "; ".join(check.problems)))
    for model in _files(base / "models", "*.json"):
        if model.resolve() in covered:
            items.append(GateItem("model", shown(model), True, "covered by a valid certificate"))
        else:
            items.append(GateItem("model", shown(model), False,
                                  f"no valid certificate covers it (run: tli certify {model})"))
    specs = _files(base / "specs", "*.toml")
    if specs:
        checker = spec_checker
        if checker is None:
            try:
                checker = _default_spec_checker()
            except ImportError as exc:
                items += [GateItem("spec", shown(s), False,
                                   f"cannot re-check specs: tli_verify.logic.check is not "
                                   f"available ({exc})") for s in specs]
                checker = None
        if checker is not None:
            items += [_spec_item(s, shown(s), checker) for s in specs]
    return GateReport(root=str(base), items=tuple(items))
