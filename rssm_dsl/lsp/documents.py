"""The open documents' texts, edited as the client says. pygls's TextDocument splits lines
with `str.splitlines()`, which also breaks at U+2028, U+2029, U+0085 and a few control
characters: an incremental edit below such a character would land on the wrong line, and the
server's text would no longer be the editor's. Here lines end only at `\\n`, `\\r\\n` and `\\r`
(positions.LineIndex), and an edit costs a binary search even on a 1 MB line.
"""

from __future__ import annotations

from collections.abc import Sequence

from lsprotocol import types as lsp
from pygls.workspace import TextDocument, Workspace

from rssm_dsl.lsp.positions import UTF16, LineIndex, split_lines


class LspLinesDocument(TextDocument):
    @property
    def lines(self) -> Sequence[str]:
        return tuple(split_lines(self.source, keepends=True))

    def _apply_incremental_change(self, change: lsp.TextDocumentContentChangePartial) -> None:
        text = self.source
        index = LineIndex(text)
        encoding = str(getattr(self.position_codec.encoding, "value",
                               self.position_codec.encoding) or UTF16)
        start = index.offset(change.range.start, encoding)
        end = index.offset(change.range.end, encoding)
        start, end = min(start, end), max(start, end)
        self._source = text[:start] + change.text + text[end:]


class LspLinesWorkspace(Workspace):
    def _create_text_document(self, doc_uri: str, source: str | None = None,
                              version: int | None = None,
                              language_id: str | None = None) -> TextDocument:
        def document(uri: str) -> LspLinesDocument:
            return LspLinesDocument(uri, source=source, version=version,
                                    language_id=language_id, sync_kind=self._sync_kind,
                                    position_codec=self._position_codec)

        try:
            return document(doc_uri)
        except ValueError:
            # a URI the URL parser refuses (`file://[x/a.rssm`: an invalid IPv6 host): the
            # document is opened all the same (the server names its file from the URI on
            # its own, paths.path_of_uri); only pygls's `path` is made up
            doc = document("untitled:document")
            doc.uri = doc_uri
            return doc


def use_lsp_lines(workspace: Workspace) -> None:
    """Make the workspace pygls created at `initialize` open its documents as above."""
    if not isinstance(workspace, LspLinesWorkspace):
        workspace.__class__ = LspLinesWorkspace
