"""Files that change on disk while a document that reads them is open: the editor's file
watcher (workspace/didChangeWatchedFiles) makes the server analyse the document again, so
its diagnostics follow an imported spec or an extern's Python module without reopening it.
The server asks for the watcher (client/registerCapability) when the editor can be asked."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import pytest_lsp
from lsprotocol import types as lsp
from pytest_lsp import ClientServerConfig, LanguageClient, client_capabilities

from tests.lsp.conftest import SERVER, track_versions
from tests.lsp.helpers import close, open_doc

# the server analyses again after its debounce (10 ms); the rest is the analysis itself
REFRESH_SECONDS = 10.0

ROOT_SPEC = """import "wf_lib.rssm"
extern shape(x: float) -> float = "wf_ops:shape"

system s {
  agent a {
    control c @ 10 Hz {
      memory x: float = gain
      behaviour b {
        update memory { x := shape(x) }
        terminal done when x > 100.0
      }
      initial b
      switch b -> b when done
    }
  }
}
"""


@pytest_lsp.fixture(config=ClientServerConfig(server_command=SERVER))
async def client(lsp_client: LanguageClient) -> AsyncIterator[None]:
    track_versions(lsp_client)
    await lsp_client.initialize_session(lsp.InitializeParams(
        capabilities=client_capabilities("visual-studio-code")))
    yield
    await lsp_client.shutdown_session()


async def _republished(client: LanguageClient, uri: str,
                       changes: list[lsp.FileEvent]) -> list[lsp.Diagnostic]:
    """Send the watcher's events; the diagnostics published next for `uri`."""
    client.diagnostics.pop(uri, None)
    client.workspace_did_change_watched_files(lsp.DidChangeWatchedFilesParams(changes=changes))
    loop = asyncio.get_running_loop()
    end = loop.time() + REFRESH_SECONDS
    while loop.time() < end:
        if uri in client.diagnostics:
            return list(client.diagnostics[uri])
        await asyncio.sleep(0.01)
    raise AssertionError(f"no new diagnostics for {uri} after the file change")


def _codes(diags: list[lsp.Diagnostic]) -> list[Any]:
    return sorted(d.code for d in diags)


@pytest.mark.asyncio
async def test_the_server_asks_for_a_watcher_of_specs_and_python_modules(
        client: LanguageClient) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + REFRESH_SECONDS
    while not client.registrations and loop.time() < end:  # type: ignore[attr-defined]
        await asyncio.sleep(0.01)
    [reg] = client.registrations  # type: ignore[attr-defined]
    assert reg.method == lsp.WORKSPACE_DID_CHANGE_WATCHED_FILES
    options = reg.register_options       # as received: JSON values
    assert isinstance(options, dict)
    globs = {w["globPattern"] for w in options["watchers"]}
    assert globs == {"**/*.rssm", "**/*.py"}


@pytest.mark.asyncio
async def test_an_imported_spec_and_a_python_module_changed_on_disk(
        client: LanguageClient, tmp_path: Path) -> None:
    lib = tmp_path / "wf_lib.rssm"
    ops = tmp_path / "wf_ops.py"
    root = tmp_path / "wf_root.rssm"
    lib.write_text("const gain: float = 0.5\n", encoding="utf-8")
    ops.write_text("def shape(x):\n    return 2.0 * x\n", encoding="utf-8")
    root.write_text(ROOT_SPEC, encoding="utf-8")
    uri = root.as_uri()
    assert await open_doc(client, root, ROOT_SPEC) == []

    # the library renames its constant: `gain` is now unknown in the open document
    lib.write_text("const gain2: float = 0.5\n", encoding="utf-8")
    got = await _republished(client, uri, [lsp.FileEvent(
        uri=lib.as_uri(), type=lsp.FileChangeType.Changed)])
    assert _codes(got) == ["E102"], got
    assert "gain" in got[0].message

    # and back
    lib.write_text("const gain: float = 0.5\n", encoding="utf-8")
    assert await _republished(client, uri, [lsp.FileEvent(
        uri=lib.as_uri(), type=lsp.FileChangeType.Changed)]) == []

    # the Python module loses the extern's function: E216 at the extern
    ops.write_text("def other(x):\n    return x\n", encoding="utf-8")
    got = await _republished(client, uri, [lsp.FileEvent(
        uri=ops.as_uri(), type=lsp.FileChangeType.Changed)])
    assert _codes(got) == ["E216"], got
    assert got[0].range.start.line == 1

    # an unrelated file changes: the document is not analysed again
    other = tmp_path / "wf_other.rssm"
    other.write_text("const unrelated: int = 1\n", encoding="utf-8")
    client.diagnostics.pop(uri, None)
    client.workspace_did_change_watched_files(lsp.DidChangeWatchedFilesParams(changes=[
        lsp.FileEvent(uri=other.as_uri(), type=lsp.FileChangeType.Changed)]))
    await asyncio.sleep(0.5)
    assert uri not in client.diagnostics
    close(client, root)
