// Starts `cso lsp` for .cso files. Everything else (diagnostics, hover,
// definitions, references, completion, formatting, outline) is the server's.
const vscode = require("vscode");
const { LanguageClient } = require("vscode-languageclient/node");

let client;

function activate(context) {
  const command = vscode.workspace.getConfiguration("cso").get("server.path") || "cso";
  const server = { command, args: ["lsp"] };
  client = new LanguageClient(
    "cso",
    "cso language server",
    { run: server, debug: server },
    { documentSelector: [{ scheme: "file", language: "cso" }] }
  );
  context.subscriptions.push({ dispose: () => client && client.stop() });
  return client.start();
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
