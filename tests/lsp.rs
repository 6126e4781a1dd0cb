//! `cso lsp` driven over stdio with JSON-RPC, as an editor drives it:
//! initialize, open a file with an error and get its diagnostic at the right
//! range, fix it and see the diagnostics clear, hover, go to a definition,
//! complete a body's faces, format, ask something it does not answer (an
//! error response, the server goes on), shut down.

use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

struct Client {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    next_id: i64,
}

impl Client {
    fn start() -> Client {
        let mut child = Command::new(env!("CARGO_BIN_EXE_cso"))
            .arg("lsp")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("cso lsp starts");
        let stdin = child.stdin.take().expect("stdin");
        let stdout = BufReader::new(child.stdout.take().expect("stdout"));
        Client {
            child,
            stdin,
            stdout,
            next_id: 1,
        }
    }

    fn send(&mut self, msg: &Value) {
        let body = msg.to_string();
        write!(self.stdin, "Content-Length: {}\r\n\r\n{body}", body.len()).expect("sent");
        self.stdin.flush().expect("flushed");
    }

    fn read(&mut self) -> Value {
        let mut length = 0;
        loop {
            let mut line = String::new();
            self.stdout.read_line(&mut line).expect("a header");
            let line = line.trim_end();
            if line.is_empty() {
                break;
            }
            if let Some(n) = line.strip_prefix("Content-Length: ") {
                length = n.parse().expect("a length");
            }
        }
        let mut body = vec![0; length];
        self.stdout.read_exact(&mut body).expect("a body");
        serde_json::from_slice(&body).expect("JSON")
    }

    /// A request's response (notifications before it are skipped).
    fn request(&mut self, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        self.send(&json!({"jsonrpc": "2.0", "id": id, "method": method, "params": params}));
        loop {
            let msg = self.read();
            if msg["id"] == json!(id) {
                return msg;
            }
        }
    }

    fn notify(&mut self, method: &str, params: Value) {
        self.send(&json!({"jsonrpc": "2.0", "method": method, "params": params}));
    }

    /// The next diagnostics published.
    fn diagnostics(&mut self) -> Vec<Value> {
        loop {
            let msg = self.read();
            if msg["method"] == "textDocument/publishDiagnostics" {
                return msg["params"]["diagnostics"]
                    .as_array()
                    .cloned()
                    .unwrap_or_default();
            }
        }
    }
}

const URI: &str = "file:///tmp/cso-lsp-test/scene.cso";

/// A scene with `steal` for `steel` on line 3 (0-based), columns 28-33.
const BROKEN: &str = "scene s { dim = 2 }
let w = 2 mm
material steel { E = 210 GPa, nu = 0.3 }
body base { material = steal, x = 0 .. w, y = 0 .. 1 mm, mesh = 4 x 2 }
fix base.bottom
traction base.top=(0,-1 MPa)
";

fn position(line: u32, character: u32) -> Value {
    json!({"textDocument": {"uri": URI}, "position": {"line": line, "character": character}})
}

#[test]
fn an_editor_session_over_stdio() {
    let mut c = Client::start();
    let init = c.request("initialize", json!({"capabilities": {}}));
    let caps = &init["result"]["capabilities"];
    assert_eq!(caps["hoverProvider"], true, "{init}");
    assert_eq!(caps["documentFormattingProvider"], true);
    c.notify("initialized", json!({}));

    // An error, at its place.
    c.notify(
        "textDocument/didOpen",
        json!({"textDocument": {"uri": URI, "languageId": "cso", "version": 1, "text": BROKEN}}),
    );
    let diags = c.diagnostics();
    assert_eq!(diags.len(), 1, "{diags:?}");
    let d = &diags[0];
    assert_eq!(d["code"], "cso::unknown-name");
    assert_eq!(d["severity"], 1);
    assert_eq!(d["range"]["start"], json!({"line": 3, "character": 23}));
    assert_eq!(d["range"]["end"], json!({"line": 3, "character": 28}));
    assert!(d["message"].as_str().unwrap_or("").contains("steel"), "{d}");

    // Fixed: no diagnostics.
    let fixed = BROKEN.replace("steal", "steel");
    c.notify(
        "textDocument/didChange",
        json!({"textDocument": {"uri": URI, "version": 2}, "contentChanges": [{"text": fixed}]}),
    );
    assert!(c.diagnostics().is_empty());

    // Hover on `w` in `x = 0 .. w`: the let's value in SI.
    let hover = c.request("textDocument/hover", position(3, 40));
    let text = hover["result"]["contents"]["value"].as_str().unwrap_or("");
    assert!(
        text.contains("let `w`") && text.contains("0.002"),
        "{hover}"
    );

    // Definition of `base` in `fix base.bottom`: the body's name on line 3.
    let def = c.request("textDocument/definition", position(4, 5));
    assert_eq!(def["result"]["uri"], URI);
    assert_eq!(
        def["result"]["range"],
        json!({"start": {"line": 3, "character": 5}, "end": {"line": 3, "character": 9}})
    );

    // References of `base`: its definition and the two conditions.
    let refs = c.request(
        "textDocument/references",
        json!({"textDocument": {"uri": URI}, "position": {"line": 3, "character": 6},
               "context": {"includeDeclaration": true}}),
    );
    assert_eq!(refs["result"].as_array().map(Vec::len), Some(3), "{refs}");

    // Completion after `base.`: its faces.
    let comp = c.request("textDocument/completion", position(4, 9));
    let labels: Vec<&str> = comp["result"]
        .as_array()
        .map(|a| a.iter().filter_map(|i| i["label"].as_str()).collect())
        .unwrap_or_default();
    assert!(
        labels.contains(&"bottom") && labels.contains(&"top"),
        "{labels:?}"
    );

    // Formatting: one edit, the canonical text.
    let fmt = c.request(
        "textDocument/formatting",
        json!({"textDocument": {"uri": URI}, "options": {"tabSize": 2, "insertSpaces": true}}),
    );
    let edits = fmt["result"].as_array().cloned().unwrap_or_default();
    assert_eq!(edits.len(), 1, "{fmt}");
    let new_text = edits[0]["newText"].as_str().unwrap_or("");
    assert_eq!(
        cso::lang::fmt::format(&fixed).ok().as_deref(),
        Some(new_text)
    );

    // The outline.
    let symbols = c.request(
        "textDocument/documentSymbol",
        json!({"textDocument": {"uri": URI}}),
    );
    let names: Vec<&str> = symbols["result"]
        .as_array()
        .map(|a| a.iter().filter_map(|s| s["name"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(names, ["s", "w", "steel", "base"]);

    // A method it does not answer, and bad parameters: errors, not an exit.
    let unknown = c.request("textDocument/rename", json!({}));
    assert_eq!(unknown["error"]["code"], -32601, "{unknown}");
    let bad = c.request("textDocument/hover", json!({"nonsense": true}));
    assert_eq!(bad["error"]["code"], -32602, "{bad}");
    let again = c.request("textDocument/hover", position(3, 40));
    assert!(again["result"]["contents"]["value"].is_string());

    let down = c.request("shutdown", Value::Null);
    assert!(down.get("error").is_none(), "{down}");
    c.notify("exit", Value::Null);
    let status = c.child.wait().expect("exits");
    assert!(status.success(), "{status:?}");
}

/// The VS Code grammar is JSON, and it highlights every item keyword, unit and
/// function the language has (so a new keyword cannot be forgotten there).
#[test]
fn the_editor_grammar_knows_the_language() {
    let path = crate::root().join("editors/vscode/syntaxes/cso.tmLanguage.json");
    let text = std::fs::read_to_string(&path).expect("the grammar");
    let grammar: Value = serde_json::from_str(&text).expect("JSON");
    let pattern = |rule: &str| {
        grammar["repository"][rule]["match"]
            .as_str()
            .unwrap_or_else(|| panic!("rule {rule}"))
            .to_string()
    };
    let words = |p: &str| -> Vec<String> {
        p.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .map(str::to_string)
            .collect()
    };
    let items = words(&pattern("item"));
    for k in cso::lang::parse::ITEM_KEYWORDS {
        assert!(items.iter().any(|w| w == k), "item keyword `{k}`");
    }
    let functions = words(&pattern("function"));
    for (name, _, _) in cso::lang::ide::docs::FUNCTIONS {
        assert!(functions.iter().any(|w| w == name), "function `{name}`");
    }
    let quantity = words(&pattern("quantity"));
    for unit in ["GPa", "MPa", "kN", "mm", "um", "kg"] {
        assert!(quantity.iter().any(|w| w == unit), "unit `{unit}`");
    }
    let package: Value = serde_json::from_str(
        &std::fs::read_to_string(crate::root().join("editors/vscode/package.json"))
            .expect("package.json"),
    )
    .expect("JSON");
    assert_eq!(
        package["contributes"]["languages"][0]["extensions"][0],
        ".cso"
    );
}
