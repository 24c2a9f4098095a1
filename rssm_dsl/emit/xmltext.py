"""XML written as text, in one pass, the way ElementTree writes it after `ET.indent`.

The PNML and CPN exports are large (tens of MB for a hundred agents) and regular; building
an ElementTree and serializing it costs far more than the net itself. These helpers write
the same bytes directly: two spaces of indentation per level, attributes in the order given,
`<tag />` for an element with neither text nor children, and ElementTree's escaping (text:
`& < >`; attribute values: also `"`, CR, LF and TAB as character references).
"""

from __future__ import annotations


def text(value: str) -> str:
    """Character data escaped as ElementTree escapes it."""
    if "&" in value:
        value = value.replace("&", "&amp;")
    if "<" in value:
        value = value.replace("<", "&lt;")
    if ">" in value:
        value = value.replace(">", "&gt;")
    return value


def attr(value: str) -> str:
    """An attribute value escaped as ElementTree escapes it (without the quotes)."""
    value = text(value)
    if '"' in value:
        value = value.replace('"', "&quot;")
    if "\r" in value:
        value = value.replace("\r", "&#13;")
    if "\n" in value:
        value = value.replace("\n", "&#10;")
    if "\t" in value:
        value = value.replace("\t", "&#09;")
    return value


def leaf(tag: str, attrs: str, value: str) -> str:
    """An element without children (``attrs`` already formatted, each with a leading space):
    ``<tag a="x">value</tag>``, or ``<tag a="x" />`` when the value is empty."""
    return f"<{tag}{attrs}>{text(value)}</{tag}>" if value else f"<{tag}{attrs} />"


class Indents:
    """The indentation of each depth, with its newline: ``pad[d] == "\\n" + "  " * d``."""

    def __init__(self) -> None:
        self._pads: list[str] = ["\n"]

    def __getitem__(self, depth: int) -> str:
        while len(self._pads) <= depth:
            self._pads.append(self._pads[-1] + "  ")
        return self._pads[depth]
