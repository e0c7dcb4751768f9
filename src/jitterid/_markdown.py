"""Escaping user text (file metadata, paths, command lines, titles) for Markdown reports,
so that it cannot inject markup, links, images or HTML into report.md."""

from __future__ import annotations

__all__ = ["md_code", "md_text"]


def md_text(text: object) -> str:
    """``text`` safe to place in Markdown prose or a table cell: one line, every markup
    character backslash-escaped, ``<`` and ``>`` as entities (so no HTML, link or image)."""
    out = []
    for ch in " ".join(str(text).split()):
        if ch == "<":
            out.append("&lt;")
        elif ch == ">":
            out.append("&gt;")
        elif ch == "&":
            out.append("&amp;")
        elif ch in "\\`*_{}[]#!|~$":
            out.append("\\" + ch)
        else:
            out.append(ch)
    return "".join(out)


def md_code(text: object) -> str:
    """An inline code span holding ``text`` verbatim (one line; fenced with more backticks
    than it contains, so it cannot close the span early)."""
    t = " ".join(str(text).split()) or "-"
    longest = run = 0
    for ch in t:
        run = run + 1 if ch == "`" else 0
        longest = max(longest, run)
    fence = "`" * (longest + 1)
    pad = " " if t.startswith("`") or t.endswith("`") else ""
    return f"{fence}{pad}{t}{pad}{fence}"
