"""Sphinx helpers of the tli-verify docs (loaded by ``docs/conf.py``).

* ``schema-fields`` directive: a JSON Schema of ``tli_verify/schemas/`` as tables of fields
  (dotted path, type, required, constraints and description), one table for the top level and
  one per object definition under ``$defs``.
* ``tli-public-api`` directive: autodoc entries for every name in ``tli_verify.__all__`` at
  build time, grouped by the module that defines it, in data-flow order.
* History references (the word "issue" and a number) in generated text -- benchmark tables
  included from ``benchmarks/results/``, docstrings and CLI help -- are dropped as the pages are
  read; the history is in the changelog.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import re
from pathlib import Path
from typing import Any

from docutils import nodes
from docutils.parsers.rst import Directive
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.nodes import nested_parse_with_titles

ROOT = Path(__file__).resolve().parents[2]

# --------------------------------------------------------------------------------------------
# History references in generated text
# --------------------------------------------------------------------------------------------

_ISSUE = r"[Ii]ssues?\s+\d+(?:\.\d+)?(?: part [A-Z])?(?: [A-Z](?![a-z]))?"
_ISSUE_PATTERNS = [
    (re.compile(r"\(" + _ISSUE + r"(?:[;:] |, (?=paper ))"), "("),
    (re.compile(r"[ \t]*\(" + _ISSUE + r"[^()]*\)"), ""),
    (re.compile(r"[;,]\s*" + _ISSUE + r"[^()]*(?=\))"), ""),
    (re.compile(r"\bIssues?\s+\d+\s+measured\b"), "An earlier measurement took"),
    (re.compile(r"\b(?:the )?" + _ISSUE + r"\s+measured\b"), "an earlier measurement took"),
    (re.compile(r"\bBefore\s+" + _ISSUE), "Previously"),
    (re.compile(r"\bbefore\s+" + _ISSUE), "previously"),
    (re.compile(r"\bof\s+" + _ISSUE), "measured earlier"),
    (re.compile(r"\b(?:the )?" + _ISSUE), "the project plan"),
]


def drop_issue_refs(text: str) -> str:
    """``text`` without references to the project's issue numbers (the changelog has them)."""
    for pattern, repl in _ISSUE_PATTERNS:
        text = pattern.sub(repl, text)
    return text


_HEADING = re.compile(r"^(#{1,6})(?= )", re.MULTILINE)


def benchmark_markdown(text: str) -> str:
    """A ``benchmarks/results/*.md`` file as a docs section.

    History references dropped; the file's own title (``# Benchmark results``) dropped (the page
    has one); every section heading one level below the page title (``make bench`` writes some
    sections with ``###``); links into ``docs/img/`` made relative to ``docs/reference/``.
    """
    text = drop_issue_refs(text)
    text = re.sub(r"\A# [^\n]*\n+", "", text)
    text = _HEADING.sub("##", text)
    return text.replace("](../../docs/img/", "](../img/")


def _on_include_read(app: Sphinx, relative_path: Path, parent_docname: str,
                     content: list[str]) -> None:
    if "benchmarks" in Path(relative_path).parts:
        content[0] = benchmark_markdown(content[0])


_RELATIVE_REF = re.compile(r":(mod|func|class|data|meth|attr|exc):`(~?)\.([A-Za-z_][\w.]*)`")


def absolute_refs(text: str, module: str, *, is_package: bool = False) -> str:
    """Relative roles of a module docstring (``:mod:`.strategies```) made absolute: a name of
    the module's package (``tli_verify.verify.strategies``), not every object whose name ends
    so (Sphinx would find ``tli_verify.testing.strategies`` too and warn)."""
    package = module if is_package else module.rsplit(".", 1)[0]

    def repl(m: re.Match[str]) -> str:
        return f":{m.group(1)}:`{m.group(2) or '~'}{package}.{m.group(3)}`"

    return _RELATIVE_REF.sub(repl, text)


def _on_docstring(app: Sphinx, what: str, name: str, obj: Any, options: Any,
                  lines: list[str]) -> None:
    text = "\n".join(lines)
    new = drop_issue_refs(text) if re.search(_ISSUE, text) else text
    if what == "module":
        new = absolute_refs(new, name, is_package=hasattr(obj, "__path__"))
    if new != text:
        lines[:] = new.split("\n")


# --------------------------------------------------------------------------------------------
# JSON Schemas as tables
# --------------------------------------------------------------------------------------------

_CONSTRAINTS = [
    ("minimum", ">= {}"), ("exclusiveMinimum", "> {}"), ("maximum", "<= {}"),
    ("exclusiveMaximum", "< {}"), ("minItems", "at least {} items"),
    ("maxItems", "at most {} items"), ("minLength", "at least {} characters"),
    ("maxLength", "at most {} characters"), ("minProperties", "at least {} keys"),
    ("maxProperties", "at most {} keys"), ("pattern", "matches {}"),
]


class _Schema:
    """One schema file and the rows of its tables."""

    def __init__(self, schema: dict[str, Any]) -> None:
        self.schema = schema
        self.defs: dict[str, Any] = schema.get("$defs", {})
        self.used: list[str] = []

    # -- helpers ------------------------------------------------------------------------------
    def _ref(self, node: dict[str, Any]) -> str | None:
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.startswith("#/$defs/"):
            return ref.removeprefix("#/$defs/")
        return None

    def complex_def(self, name: str) -> bool:
        """Whether a definition gets its own table (an object with fields)."""
        node = self.defs.get(name, {})
        return bool(node.get("properties")) or any(
            isinstance(alt, dict) and alt.get("properties")
            for alt in node.get("oneOf", []) + node.get("anyOf", []))

    def _resolve(self, node: dict[str, Any]) -> dict[str, Any]:
        """A simple definition inlined into the node that refers to it."""
        name = self._ref(node)
        if name is None or self.complex_def(name):
            return node
        merged = dict(self._resolve(self.defs.get(name, {})))
        merged.update({k: v for k, v in node.items() if k != "$ref"})
        return merged

    def _mention(self, name: str) -> str:
        if name not in self.used:
            self.used.append(name)
        return f"{name} (see below)"

    def type_of(self, node: dict[str, Any]) -> str:
        """A short type expression: ``array of number``, ``string or null``, ..."""
        name = self._ref(node)
        if name is not None and self.complex_def(name):
            return self._mention(name)
        node = self._resolve(node)
        if "const" in node:
            return f"constant {json.dumps(node['const'])}"
        if "enum" in node:
            return "one of " + ", ".join(json.dumps(v) for v in node["enum"])
        for key in ("oneOf", "anyOf"):
            if key in node:
                return " or ".join(self.type_of(alt) for alt in node[key])
        kinds = node.get("type")
        if kinds is None:
            return "any"
        names = [kinds] if isinstance(kinds, str) else list(kinds)
        out = []
        for kind in names:
            if kind == "array" and isinstance(node.get("items"), dict):
                out.append("array of " + self.type_of(node["items"]))
            elif kind == "object" and isinstance(node.get("additionalProperties"), dict) \
                    and not node.get("properties"):
                out.append("table: name -> " + self.type_of(node["additionalProperties"]))
            else:
                out.append(kind)
        return " or ".join(out)

    def constraints(self, node: dict[str, Any]) -> str:
        node = self._resolve(node)
        parts = [fmt.format(json.dumps(node[key]) if key == "pattern" else node[key])
                 for key, fmt in _CONSTRAINTS if key in node]
        if node.get("uniqueItems"):
            parts.append("items unique")
        names = node.get("propertyNames")
        if isinstance(names, dict) and names.get("pattern"):
            parts.append(f"names match {json.dumps(names['pattern'])}")
        items = node.get("items")
        if isinstance(items, dict) and not self._ref(items):
            inner = self.constraints(items)
            if inner:
                parts.append(f"each item: {inner}")
        return "; ".join(parts)

    def description(self, node: dict[str, Any]) -> str:
        text = node.get("description") or self._resolve(node).get("description") or ""
        rules = [rule.get("description") for key in ("allOf", "anyOf")
                 for rule in node.get(key, []) if isinstance(rule, dict)
                 and rule.get("description")]
        return " ".join([text, *[str(r) for r in rules]]).strip()

    # -- rows ---------------------------------------------------------------------------------
    def rows(self, node: dict[str, Any], prefix: str = "") -> list[list[str]]:
        """One row per field of ``node`` (an object schema), nested objects expanded."""
        out: list[list[str]] = []
        required = set(node.get("required", []))
        for name, sub in node.get("properties", {}).items():
            if not isinstance(sub, dict):
                continue
            path = prefix + name
            out.append([path, self.type_of(sub), "yes" if name in required else "",
                        self.constraints(sub), self.description(sub)])
            out.extend(self.children(sub, path))
        return out

    def children(self, sub: dict[str, Any], path: str) -> list[list[str]]:
        """The rows of what a field holds: an inline object, its items, its table values."""
        if self._ref(sub):
            return []
        if sub.get("properties"):
            return self.rows(sub, path + ".")
        items = sub.get("items")
        if isinstance(items, dict) and not self._ref(items):
            if items.get("properties"):
                return self.rows(items, path + "[].")
        extra = sub.get("additionalProperties")
        if isinstance(extra, dict) and not self._ref(extra):
            if extra.get("properties"):
                return self.rows(extra, path + ".NAME.")
            return self.children(extra, path + ".NAME")
        for key in ("oneOf", "anyOf"):
            for alt in sub.get(key, []):
                if isinstance(alt, dict) and alt.get("properties") and not self._ref(alt):
                    return self.rows(alt, path + ".")
        return []

    def def_rows(self, name: str) -> list[list[str]]:
        node = self.defs[name]
        if node.get("properties"):
            return self.rows(node)
        out: list[list[str]] = []
        for key in ("oneOf", "anyOf"):
            for i, alt in enumerate(node.get(key, []), start=1):
                if isinstance(alt, dict):
                    out.append([f"(form {i})", self.type_of(alt), "", self.constraints(alt),
                                self.description(alt)])
                    out.extend(self.children(alt, f"(form {i})"))
        return out


def _table(header: list[str], rows: list[list[str]], widths: list[int]) -> nodes.table:
    table = nodes.table(classes=["schema-table"])
    group = nodes.tgroup(cols=len(header))
    table += group
    for width in widths:
        group += nodes.colspec(colwidth=width)
    head = nodes.thead()
    group += head
    row = nodes.row()
    for cell in header:
        row += nodes.entry("", nodes.paragraph(text=cell))
    head += row
    body = nodes.tbody()
    group += body
    for values in rows:
        row = nodes.row()
        for i, cell in enumerate(values):
            para = nodes.paragraph()
            if i == 0 and cell:
                para += nodes.literal(text=cell)
            else:
                para += nodes.Text(cell)
            row += nodes.entry("", para)
        body += row
    return table


HEADER = ["field", "type", "required", "constraints", "description"]
WIDTHS = [22, 18, 8, 18, 34]


class SchemaFields(Directive):
    """``schema-fields PATH``: the fields of a JSON Schema file (path from the repository root)."""

    required_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        path = ROOT / self.arguments[0]
        env = self.state.document.settings.env
        env.note_dependency(str(path))
        schema = _Schema(json.loads(path.read_text(encoding="utf-8")))
        out: list[nodes.Node] = []
        title = schema.schema.get("title")
        if title:
            out.append(nodes.paragraph("", "", nodes.strong(text=title)))
        text = schema.schema.get("description")
        if text:
            out.append(nodes.paragraph(text=text))
        rules = [r.get("description") for r in schema.schema.get("allOf", [])
                 if isinstance(r, dict) and r.get("description")]
        for rule in rules:
            out.append(nodes.paragraph(text=f"Rule: {rule}"))
        out.append(nodes.rubric(text="Fields"))
        out.append(_table(HEADER, schema.rows(schema.schema), WIDTHS))
        done: set[str] = set()
        while True:
            todo = [name for name in schema.used if name not in done]
            if not todo:
                break
            for name in todo:
                done.add(name)
                out.append(nodes.rubric(text=f"{name}"))
                text = schema.defs[name].get("description")
                if text:
                    out.append(nodes.paragraph(text=text))
                out.append(_table(HEADER, schema.def_rows(name), WIDTHS))
        return out


# --------------------------------------------------------------------------------------------
# The public API from tli_verify.__all__
# --------------------------------------------------------------------------------------------

_FLOW = ["tli_verify._version", "tli_verify.logic", "tli_verify.tasks", "tli_verify.demos",
         "tli_verify.api", "tli_verify.model", "tli_verify.certification", "tli_verify.runtime",
         "tli_verify.verify", "tli_verify.deploy", "tli_verify.errors"]


def _home(package: Any, name: str, obj: Any) -> str:
    table = getattr(package, "_NAMES", None)
    if isinstance(table, dict) and isinstance(table.get(name), str):
        return table[name]
    module = getattr(obj, "__module__", None)
    return module if isinstance(module, str) else package.__name__


def _rank(module: str) -> tuple[int, str]:
    for i, prefix in enumerate(_FLOW):
        if module == prefix or module.startswith(prefix + "."):
            return i, module
    return len(_FLOW), module


def _import_all(package: Any) -> None:
    """Import every submodule, so that the API page sees the namespace as users will."""
    import pkgutil

    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        importlib.import_module(info.name)


def public_api_rst(package_name: str = "tli_verify") -> list[str]:
    """The autodoc directives documenting ``package.__all__``, grouped by home module."""
    package = importlib.import_module(package_name)
    _import_all(package)
    groups: dict[str, list[tuple[str, Any]]] = {}
    for name in package.__all__:
        attr = getattr(package, name)
        home = _home(package, name, attr)
        obj = getattr(importlib.import_module(home), name, attr)
        groups.setdefault(home, []).append((name, obj))
    lines: list[str] = []
    for module in sorted(groups, key=_rank):
        lines += [f".. rubric:: From ``{module}``", ""]
        for name, obj in groups[module]:
            target = f"{package_name}.{name}"
            if getattr(package, name) is not obj:
                # the attribute was replaced, e.g. by a subpackage of the same name
                target = f"{module}.{name}"
                lines += [f"Public name ``{package_name}.{name}``, documented here at its home "
                          f"``{target}``: once the subpackage ``{package_name}.{name}`` is "
                          f"imported, the attribute ``{package_name}.{name}`` is that "
                          "subpackage.", ""]
            if inspect.isclass(obj) and issubclass(obj, BaseException):
                lines += [f".. autoexception:: {target}", ""]
            elif inspect.isclass(obj):
                lines += [f".. autoclass:: {target}", "   :members:", ""]
            elif callable(obj):
                lines += [f".. autofunction:: {target}", ""]
            else:
                lines += [f".. autodata:: {target}", "   :no-value:", ""]
    return lines


class PublicApi(Directive):
    """``tli-public-api``: every name of ``tli_verify.__all__``, documented by autodoc."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(public_api_rst(), "tli-public-api"),
                                 container)
        return list(container.children)


# --------------------------------------------------------------------------------------------
# Every module's docstring, by layer
# --------------------------------------------------------------------------------------------

#: modules documented with their public members (their ``__all__``), not just their docstring
WITH_MEMBERS: set[str] = set()


def module_index_rst(package_name: str = "tli_verify") -> list[str]:
    """``automodule`` entries for every module of the package, one section per subpackage."""
    import pkgutil

    package = importlib.import_module(package_name)
    public = set(getattr(package, "__all__", []))
    groups: dict[str, list[str]] = {}
    for info in pkgutil.walk_packages(package.__path__, package_name + "."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        top = ".".join(info.name.split(".")[:2])
        groups.setdefault(top if info.ispkg or top != info.name else "", []).append(info.name)
    lines: list[str] = []
    for top in sorted(groups, key=lambda name: (name != "", name)):
        title = f"``{top}``" if top else "Top-level modules"
        lines += [title, "-" * len(title), ""]
        for name in groups[top]:
            lines += [f".. automodule:: {name}"]
            if name.rsplit(".", 1)[-1] in public and name.count(".") == 1:
                # a subpackage whose name is also a public function (tli_verify.certification):
                # the API page owns the name
                lines += ["   :no-index:"]
            if name in WITH_MEMBERS:
                lines += ["   :members:"]
            lines += [""]
    return lines


class ModuleIndex(Directive):
    """``tli-module-index``: the docstring of every module of ``tli_verify``."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(module_index_rst(), "tli-module-index"),
                                 container)
        return list(container.children)


# --------------------------------------------------------------------------------------------
# The CLI parser, its help text escaped for reST
# --------------------------------------------------------------------------------------------

_RST_SPECIAL = re.compile(r"([\\*|`])|(_)(?=\W|$)")


def rst_text(text: str | None) -> str | None:
    """Plain help text as reST: ``*``, ``|``, backquotes and trailing ``_`` stay literal;
    history references dropped (the changelog has them)."""
    if text is None or text is argparse.SUPPRESS:
        return text
    text = drop_issue_refs(text)
    return _RST_SPECIAL.sub(lambda m: "\\" + (m.group(1) or m.group(2)), text)


def rst_block(text: str | None) -> str | None:
    """A description or epilog as reST: laid out by hand (indented lines, as a
    ``RawDescriptionHelpFormatter`` prints them) it becomes a literal block, else
    :func:`rst_text`."""
    if text is None or text is argparse.SUPPRESS:
        return text
    if any(line[:1].isspace() for line in text.splitlines()[1:] if line.strip()):
        body = "\n".join("    " + line if line.strip() else "" for line in
                         drop_issue_refs(text).splitlines())
        return "::\n\n" + body + "\n"
    return rst_text(text)


def _escape_parser(parser: argparse.ArgumentParser, seen: set[int]) -> None:
    if id(parser) in seen:
        return
    seen.add(id(parser))
    parser.description = rst_block(parser.description)
    parser.epilog = rst_block(parser.epilog)
    for action in parser._actions:
        action.help = rst_text(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = rst_text(choice.help)
            for sub in action.choices.values():
                _escape_parser(sub, seen)


def cli_parser() -> argparse.ArgumentParser:
    """``tli_verify.cli.build_parser()`` with its help text escaped for sphinx-argparse."""
    from tli_verify.cli import build_parser

    parser = build_parser()
    _escape_parser(parser, set())
    return parser


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("schema-fields", SchemaFields)
    app.add_directive("tli-public-api", PublicApi)
    app.add_directive("tli-module-index", ModuleIndex)
    app.connect("include-read", _on_include_read)
    app.connect("autodoc-process-docstring", _on_docstring)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
