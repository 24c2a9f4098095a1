"""The cyclic garbage collector paused while a large structure is built.

The compiler, the language server's index and the JSON decoder allocate millions of small
objects and free none of them in cycles; the collector's passes over them only rescan them
(30 % of a large compilation; three times the decoding of 8 MB of ``[[],...]``).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused() -> Iterator[None]:
    """The collector off inside the block, back on after it if it was on."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
