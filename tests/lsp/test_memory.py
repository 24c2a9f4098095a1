"""The server keeps the objects of a published analysis out of the cyclic collector's way
(rssm_dsl/lsp/memory.py): collections set off by requests do not visit them; a full
collection at idle time still frees the cycles among them."""

from __future__ import annotations

import gc
import weakref

from rssm_dsl.lsp import memory


class _Node:
    def __init__(self) -> None:
        self.me = self      # a cycle: only the cyclic collector frees it


def test_settled_objects_are_skipped_by_collections_and_freed_at_idle() -> None:
    try:
        node = _Node()
        alive = weakref.ref(node)
        memory.settle()
        assert gc.get_freeze_count() > 0
        del node
        gc.collect()                 # what a request's allocations may set off
        assert alive() is not None   # frozen: not visited
        memory.collect()             # idle
        assert alive() is None
        assert gc.get_freeze_count() > 0     # the survivors kept off again
    finally:
        gc.unfreeze()
