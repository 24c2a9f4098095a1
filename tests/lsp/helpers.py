"""Helpers for the LSP tests: open documents, wait for their diagnostics, apply edits."""

from __future__ import annotations

import asyncio
from pathlib import Path

from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.lsp.positions import LineIndex

ROOT = Path(__file__).resolve().parents[2]
# the paper's example as of this test suite (examples/ may evolve on its own)
EXAMPLE = Path(__file__).resolve().parent / "data" / "circle.rssm"


async def open_doc(client: LanguageClient, path: Path, text: str, version: int = 1
                   ) -> list[lsp.Diagnostic]:
    uri = path.as_uri()
    client.diagnostics.pop(uri, None)
    client.text_document_did_open(lsp.DidOpenTextDocumentParams(
        text_document=lsp.TextDocumentItem(uri=uri, language_id="rssm", version=version,
                                           text=text)))
    return await diagnostics_of(client, uri, version)


async def diagnostics_of(client: LanguageClient, uri: str, version: int,
                         timeout: float = 30.0) -> list[lsp.Diagnostic]:
    """Wait for the diagnostics published for `version` of the document."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while loop.time() < end:
        if uri in client.diagnostics and client.diagnostic_versions.get(uri) == version:
            return list(client.diagnostics[uri])
        await asyncio.sleep(0.02)
    raise AssertionError(f"no diagnostics for {uri} version {version}")


def change(client: LanguageClient, path: Path, text: str, version: int) -> None:
    """Replace the whole text (a full-document change)."""
    client.text_document_did_change(lsp.DidChangeTextDocumentParams(
        text_document=lsp.VersionedTextDocumentIdentifier(uri=path.as_uri(), version=version),
        content_changes=[lsp.TextDocumentContentChangeWholeDocument(text=text)]))


def close(client: LanguageClient, path: Path) -> None:
    client.text_document_did_close(lsp.DidCloseTextDocumentParams(
        text_document=lsp.TextDocumentIdentifier(uri=path.as_uri())))


def position_of(text: str, needle: str, nth: int = 0, delta: int = 0,
                encoding: str = "utf-16") -> lsp.Position:
    """The position of the nth occurrence of `needle` (plus delta code points)."""
    at = -1
    for _ in range(nth + 1):
        at = text.index(needle, at + 1)
    return LineIndex(text).position(at + delta, encoding)


def apply_edits(text: str, edits: list[lsp.TextEdit], encoding: str = "utf-16") -> str:
    lines = LineIndex(text)
    spans = sorted(((lines.offset(e.range.start, encoding), lines.offset(e.range.end, encoding),
                     e.new_text) for e in edits), reverse=True)
    for start, end, new in spans:
        text = text[:start] + new + text[end:]
    return text
