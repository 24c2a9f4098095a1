// The RSSM extension: starts `rssmc lsp` (the language server of the rssmc compiler) for
// .rssm files. Highlighting comes from syntaxes/rssm.tmLanguage.json.
"use strict";

const vscode = require("vscode");
const { LanguageClient, TransportKind } = require("vscode-languageclient/node");

let client;

function serverOptions() {
  const config = vscode.workspace.getConfiguration("rssm");
  const command = config.get("server.command", ["rssmc", "lsp"]);
  if (!Array.isArray(command) || command.length === 0) {
    throw new Error("rssm.server.command must be a non-empty list, e.g. [\"rssmc\", \"lsp\"]");
  }
  return {
    command: command[0],
    args: command.slice(1),
    transport: TransportKind.stdio,
  };
}

async function activate(context) {
  const clientOptions = {
    documentSelector: [
      { scheme: "file", language: "rssm" },
      { scheme: "untitled", language: "rssm" },
    ],
    // no `synchronize.fileEvents`: the server registers its own watcher (.rssm and .py
    // files) through client/registerCapability, which the language client supports
  };
  client = new LanguageClient("rssm", "RSSM language server", serverOptions(), clientOptions);
  context.subscriptions.push(
    vscode.commands.registerCommand("rssm.restartServer", async () => {
      if (client) {
        await client.restart();
      }
    }),
  );
  await client.start();
}

async function deactivate() {
  if (client) {
    await client.stop();
  }
}

module.exports = { activate, deactivate };
