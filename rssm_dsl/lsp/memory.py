"""The cyclic garbage collector in a server that keeps large trees.

An analysis allocates millions of small objects (the AST, the symbol index, diagnostics) and
keeps them until the next one. A full collection of Python's cyclic collector visits every
object it tracks: tens of milliseconds for the analysis of a large file, at whatever moment
an allocation sets it off, such as in the middle of a hover. So after each analysis is
published, :func:`settle` moves every tracked object into the permanent generation
(``gc.freeze``), and the collections that requests set off look at new objects only. When the
server has been idle for a while, :func:`collect` unfreezes and collects everything (the
cycles among the objects of older analyses are freed then) and freezes what is left.
"""

from __future__ import annotations

import gc

IDLE_SECONDS = 2.0     # idle time before a full collection


def settle() -> None:
    """Keep the collector off the objects alive now (an analysis just published)."""
    gc.freeze()


def collect() -> None:
    """A full collection of everything, then the survivors kept off again."""
    gc.unfreeze()
    gc.collect()
    gc.freeze()
