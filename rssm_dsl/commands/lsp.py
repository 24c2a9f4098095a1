"""`rssmc lsp`: the language server (LSP on stdio) for editors."""

from __future__ import annotations

import typer

from rssm_dsl.commands.common import EXIT_OK, guarded


def lsp() -> None:
    """Run the RSSM language server on stdin/stdout (for VS Code, Neovim and other editors):
    diagnostics, hover, definition, references, completion, symbols, rename, formatting and
    quick fixes."""

    def run() -> int:
        from rssm_dsl.lsp.server import serve

        serve()
        return EXIT_OK

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("lsp")(lsp)
