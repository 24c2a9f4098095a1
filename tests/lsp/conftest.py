"""pytest-lsp fixtures: `rssmc lsp` runs as a subprocess; the client speaks LSP to it."""

from __future__ import annotations

import sys
from collections.abc import AsyncIterator
from pathlib import Path

import pytest_lsp
from lsprotocol import types as lsp
from pytest_lsp import ClientServerConfig, LanguageClient, client_capabilities


def track_versions(client: LanguageClient) -> None:
    """Record the version of every publishDiagnostics (the default handler drops it), and
    answer client/registerCapability as an editor does (recording what is registered)."""
    versions: dict[str, int | None] = {}
    client.diagnostic_versions = versions  # type: ignore[attr-defined]
    registrations: list[lsp.Registration] = []
    client.registrations = registrations  # type: ignore[attr-defined]

    @client.feature(lsp.CLIENT_REGISTER_CAPABILITY)
    def register(params: lsp.RegistrationParams) -> None:
        registrations.extend(params.registrations)

    def publish(params: lsp.PublishDiagnosticsParams) -> None:
        client.diagnostics[params.uri] = params.diagnostics
        versions[params.uri] = params.version

    client.protocol.fm.features[lsp.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS] = publish


ROOT = Path(__file__).resolve().parents[2]
SERVER = [sys.executable, "-m", "rssm_dsl", "lsp"]


@pytest_lsp.fixture(scope="module", config=ClientServerConfig(server_command=SERVER))
async def client(lsp_client: LanguageClient) -> AsyncIterator[None]:
    """A client with the capabilities of VS Code (UTF-16 positions)."""
    params = lsp.InitializeParams(
        capabilities=client_capabilities("visual-studio-code"),
        root_uri=ROOT.as_uri(),
    )
    track_versions(lsp_client)
    await lsp_client.initialize_session(params)
    yield
    await lsp_client.shutdown_session()
