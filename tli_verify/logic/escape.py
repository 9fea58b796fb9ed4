"""Escaping names and labels for the text formats the tool writes.

Spec names, mode names and labels come from user files. Written raw into Graphviz DOT or
Markdown, a quote, a bracket or a newline changes the document's structure (e.g. the name
``ti"ny"; evil [label=x]`` breaks out of ``digraph "..."``). JSON needs nothing here: the
standard library's encoder escapes every string.
"""

from __future__ import annotations

from urllib.parse import quote

__all__ = ["dot_string", "dot_unescape", "markdown_text", "markdown_url"]

_MARKDOWN_SPECIALS = frozenset("\\`*_[]<>|&!#~")


def dot_string(text: str) -> str:
    """``text`` as a double-quoted DOT string whose content is ``text`` exactly.

    Backslash and double quote are backslash-escaped (a bare backslash would start a Graphviz
    label escape such as ``\\N``); a line break becomes DOT's ``\\n`` and any other control
    character is dropped, so the result is one line that cannot end the string early.

    Parameters
    ----------
    text : str

    Returns
    -------
    str
        ``"..."``, quotes included.
    """
    out = []
    for ch in text.replace("\r\n", "\n"):  # one line break, however written
        if ch in '\\"':
            out.append("\\" + ch)
        elif ch in "\r\n":
            out.append("\\n")
        elif ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0:
            continue
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def dot_unescape(quoted: str) -> str:
    """Inverse of :func:`dot_string` on its output (for tests and readers)."""
    if len(quoted) < 2 or quoted[0] != '"' or quoted[-1] != '"':
        raise ValueError(f"not a quoted DOT string: {quoted!r}")
    body = quoted[1:-1]
    out = []
    i = 0
    while i < len(body):
        ch = body[i]
        if ch == "\\" and i + 1 < len(body):
            nxt = body[i + 1]
            out.append("\n" if nxt == "n" else nxt)
            i += 2
            continue
        out.append(ch)
        i += 1
    return "".join(out)


def markdown_text(text: str) -> str:
    """``text`` as inline Markdown that renders literally (also inside a table cell).

    Markdown's punctuation (CommonMark backslash escapes), the table separator ``|`` and
    HTML's ``<``, ``>`` and ``&`` are backslash-escaped; line breaks become spaces (a newline
    would end a table row).
    """
    out = []
    for ch in text:
        if ch in _MARKDOWN_SPECIALS:
            out.append("\\" + ch)
        elif ch in "\r\n" or ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(" ")
        else:
            out.append(ch)
    return "".join(out)


def markdown_url(path: str) -> str:
    """A relative path as a Markdown link target: percent-encoded, ``/`` kept."""
    return quote(path, safe="/")
