"""Function-level imports of our own modules, each with the reason it is not at the top.

An import of a ``tli_verify`` module inside a function is kept only when it has a reason:

- ``heavy``: importing the module at the top would load a third-party package the importing
  module does not load by itself (e.g. ``cvxpy``, ``mujoco``, ``matplotlib``, ``numpy`` for the
  CLI): the lazy import keeps start-up fast;
- ``cycle``: the imported module imports the importing one (at its top, or through others):
  a top-level import would be circular;
- ``lazy``: a package ``__init__`` that exposes its submodules on first use;
- ``inert``: the pytest plugin, loaded by every pytest run in an environment with tli-verify
  installed, imports nothing of ours until a run uses it (tested).

Every other one can move to the top. What each module loads is measured, not guessed: each
module is imported in a fresh interpreter and ``sys.modules`` read.

Usage::

    python scripts/function_imports.py            # the table and the counts
    python scripts/function_imports.py --hoist    # move the unjustified ones to the top
    python scripts/function_imports.py --check    # exit 1 if one is unjustified
"""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "tli_verify"

_PROBE = """
import json, sys
before = set(sys.modules)
import importlib
importlib.import_module(sys.argv[1])
print(json.dumps(sorted(set(sys.modules) - before)))
"""


@dataclass(frozen=True)
class FunctionImport:
    """One ``import``/``from ... import`` of a ``tli_verify`` module inside a function."""

    path: Path
    module: str  # the importing module
    target: str  # the imported module
    names: tuple[tuple[str, str | None], ...]  # (name, alias) of a from-import; () for import
    lineno: int
    end_lineno: int
    function: str
    guarded: bool = False  # inside a ``try`` (the import's failure is handled) or alone in a block


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(node: ast.ImportFrom, module: str, is_pkg: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def function_imports(path: Path) -> Iterator[FunctionImport]:
    tree = ast.parse(path.read_text(), str(path))
    module = module_name(path)
    is_pkg = path.name == "__init__.py"

    def visit(node: ast.AST, func: str | None, guarded: bool = False
              ) -> Iterator[FunctionImport]:
        body = getattr(node, "body", None)
        alone = isinstance(body, list) and all(
            isinstance(b, (ast.Import, ast.ImportFrom)) for b in body)
        for child in ast.iter_child_nodes(node):
            name = func
            g = guarded or isinstance(node, ast.Try) or alone
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = child.name if func is None else f"{func}.{child.name}"
            if func is not None and isinstance(child, ast.ImportFrom):
                target = _resolve(child, module, is_pkg)
                if target.split(".")[0] == "tli_verify":
                    yield FunctionImport(path, module, target,
                                         tuple((a.name, a.asname) for a in child.names),
                                         child.lineno, child.end_lineno or child.lineno, func,
                                         g)
            elif func is not None and isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name.split(".")[0] == "tli_verify":
                        yield FunctionImport(path, module, alias.name, (), child.lineno,
                                             child.end_lineno or child.lineno, func, g)
            yield from visit(child, name, guarded or isinstance(node, ast.Try))

    yield from visit(tree, None)


def loads(module: str) -> list[str]:
    """The modules a fresh ``import module`` loads."""
    out = subprocess.run([sys.executable, "-c", _PROBE, module], capture_output=True, text=True,
                         cwd=ROOT, check=False)
    if out.returncode != 0:
        return ["<import failed>"]
    return json.loads(out.stdout)


def _third_party(mods: list[str]) -> set[str]:
    std = set(sys.stdlib_module_names)
    return {m.split(".")[0] for m in mods} - std - {"tli_verify", "_distutils_hack"} - {
        m for m in {x.split(".")[0] for x in mods} if m.startswith("__editable__")}


def reason(imp: FunctionImport, load: dict[str, list[str]]) -> str | None:
    """Why ``imp`` stays in its function, or None if it can move to the top."""
    if imp.path.name == "__init__.py":
        return "lazy: the package exposes its submodules on first use"
    if imp.module == "tli_verify.testing.plugin":
        return "inert: the pytest plugin loads nothing of ours until a run uses it"
    if imp.guarded:
        return "guarded: inside a try (its failure is handled) or the only statement of a block"
    target = imp.target
    # ``from tli_verify.a import b``: b may be a submodule
    targets = [target] + [f"{target}.{n}" for n, _ in imp.names if f"{target}.{n}" in load]
    own = set(load.get(imp.module, []))
    needed: set[str] = set()
    for t in targets:
        mods = load.get(t)
        if mods is None:
            continue
        if imp.module in mods or imp.module == t:
            return f"cycle: {t} imports {imp.module}"
        needed |= _third_party(mods)
    extra = sorted(needed - _third_party(list(own)))
    named = [m for m in extra if not m.startswith("_")]  # not cython's or sysconfig's helpers
    extra = named or extra
    if extra:
        more = ", ..." if len(extra) > 4 else ""
        return f"heavy: keeps {', '.join(extra[:4])}{more} from loading"
    return None


def collect() -> tuple[list[FunctionImport], dict[str, list[str]]]:
    imps = [i for p in sorted(PKG.rglob("*.py")) for i in function_imports(p)]
    mods = {module_name(p) for p in PKG.rglob("*.py")}
    with ThreadPoolExecutor(4) as pool:
        load = dict(zip(sorted(mods), pool.map(loads, sorted(mods)), strict=True))
    return imps, load


def hoist(imps: list[FunctionImport], load: dict[str, list[str]]) -> int:
    """Move each unjustified import to the top of its module (names kept as the function
    bound them); skip one whose name would clash with another binding of the module."""
    by_file: dict[Path, list[FunctionImport]] = {}
    for imp in imps:
        if reason(imp, load) is None:
            by_file.setdefault(imp.path, []).append(imp)
    moved = 0
    for path, group in by_file.items():
        text = path.read_text()
        tree = ast.parse(text)
        top_names = _top_level_names(tree)
        bound: dict[str, str] = {}  # name -> "module.attr" it is bound to at the top
        ok: list[FunctionImport] = []
        for imp in group:
            pairs = ([(a or n, f"{imp.target}.{n}") for n, a in imp.names] if imp.names
                     else [(imp.target.split(".")[0], imp.target.split(".")[0])])
            if imp.names == () and "." in imp.target:
                pairs = [("tli_verify", "tli_verify")]
            clash = any((name in top_names and top_names[name] != src)
                        or (name in bound and bound[name] != src) for name, src in pairs)
            if clash:
                continue
            for name, src in pairs:
                bound[name] = src
            ok.append(imp)
        if not ok:
            continue
        lines = text.splitlines(keepends=True)
        drop: set[int] = set()
        for imp in ok:
            drop.update(range(imp.lineno - 1, imp.end_lineno))
        new_imports = sorted({_statement(imp) for imp in ok} - _top_statements(tree))
        kept = [line for i, line in enumerate(lines) if i not in drop]
        # a function left with a blank line where its imports were: drop a doubled blank
        out: list[str] = []
        for line in kept:
            if out and not line.strip() and not out[-1].strip() and _indent_of_next(out):
                continue
            out.append(line)
        at = _after_last_top_import(ast.parse("".join(out)))
        body = "".join(out[:at]) + "".join(s + "\n" for s in new_imports) + "".join(out[at:])
        path.write_text(body)
        moved += len(ok)
    return moved


def _indent_of_next(out: list[str]) -> bool:
    return len(out) >= 1 and out[-1].strip() == "" and len(out) >= 2 and out[-2].startswith(" ")


def _statement(imp: FunctionImport) -> str:
    if not imp.names:
        return f"import {imp.target}"
    parts = [n if a is None else f"{n} as {a}" for n, a in imp.names]
    return f"from {imp.target} import {', '.join(parts)}"


def _top_statements(tree: ast.Module) -> set[str]:
    out = set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 0:
            for a in node.names:
                what = a.name if a.asname is None else f"{a.name} as {a.asname}"
                out.add(f"from {node.module} import {what}")
    return out


def _top_level_names(tree: ast.Module) -> dict[str, str]:
    names: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 0:
            for a in node.names:
                names[a.asname or a.name] = f"{node.module}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                top = a.name.split(".")[0]
                names[a.asname or top] = (a.asname and a.name) or top
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names[node.name] = "<def>"
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            for t in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                for n in ast.walk(t):
                    if isinstance(n, ast.Name):
                        names[n.id] = "<assign>"
    return names


def _after_last_top_import(tree: ast.Module) -> int:
    """The line after which new top-level imports go: the end of the leading run of imports
    (the docstring and ``if TYPE_CHECKING:`` blocks may sit among them)."""
    last = 0
    for i, node in enumerate(tree.body):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            last = node.end_lineno or node.lineno
        elif i == 0 and isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            continue
        elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            continue
        else:
            break
    return last


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hoist", action="store_true")
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args(argv)
    imps, load = collect()
    if args.hoist:
        print(f"moved {hoist(imps, load)} imports to the top")
        imps, load = collect()
    rows = [(i, reason(i, load)) for i in imps]
    kinds: dict[str, int] = {}
    for imp, why in rows:
        key = "none" if why is None else why.split(":")[0]
        kinds[key] = kinds.get(key, 0) + 1
        if why is None or not (args.check or args.hoist):
            print(f"{imp.path.relative_to(ROOT)}:{imp.lineno}: {imp.function}: "
                  f"{imp.target}: {why or 'NO REASON (can move to the top)'}")
    print(f"{len(rows)} function-level imports of our own modules: "
          + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())))
    return 1 if args.check and kinds.get("none") else 0


if __name__ == "__main__":
    sys.exit(main())
