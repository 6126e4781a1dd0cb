//! `cso lsp`: a language server over stdio for any editor that speaks the
//! Language Server Protocol.
//!
//! lsp-server (rust-analyzer's transport: JSON-RPC framing, the initialize
//! and shutdown handshakes, crossbeam channels) with lsp-types' messages: a
//! synchronous loop fits a server whose every answer is a front-end check of
//! one file (no async runtime to carry). What it answers comes from
//! [`cso::lang::ide`]; this file turns byte offsets into LSP positions
//! (lines and UTF-16 columns) and back, and never exits on a bad message: an
//! unknown method, bad parameters or a panic in an answer is an LSP error
//! response, and the loop goes on.

use super::print::{fail, Outcome, EXIT_IO};
use cso::lang::ast::Span;
use cso::lang::ide::{Analysis, CompletionKind as Kind, NameKind};
use cso::lang::CheckOptions;
use lsp_server::{Connection, ErrorCode, Message, Notification, Request, Response};
use lsp_types as lsp;
use std::collections::HashMap;

/// Runs the server until the client shuts it down.
pub fn run() -> Outcome {
    let (connection, io) = Connection::stdio();
    let caps = lsp::ServerCapabilities {
        text_document_sync: Some(lsp::TextDocumentSyncCapability::Kind(
            lsp::TextDocumentSyncKind::FULL,
        )),
        hover_provider: Some(lsp::HoverProviderCapability::Simple(true)),
        definition_provider: Some(lsp::OneOf::Left(true)),
        references_provider: Some(lsp::OneOf::Left(true)),
        completion_provider: Some(lsp::CompletionOptions {
            trigger_characters: Some(vec![".".into()]),
            ..Default::default()
        }),
        document_formatting_provider: Some(lsp::OneOf::Left(true)),
        document_symbol_provider: Some(lsp::OneOf::Left(true)),
        ..Default::default()
    };
    let caps = serde_json::to_value(caps).map_err(|e| fail(EXIT_IO, e))?;
    connection
        .initialize(caps)
        .map_err(|e| fail(EXIT_IO, format!("lsp: {e}")))?;
    let mut server = Server::default();
    for msg in &connection.receiver {
        match msg {
            Message::Request(req) => {
                match connection.handle_shutdown(&req) {
                    Ok(true) => break,
                    Ok(false) => {}
                    Err(e) => return Err(fail(EXIT_IO, format!("lsp: {e}"))),
                }
                let resp = server.answer(req);
                if connection.sender.send(Message::Response(resp)).is_err() {
                    break;
                }
            }
            Message::Notification(n) => {
                for out in server.notified(n) {
                    if connection.sender.send(Message::Notification(out)).is_err() {
                        break;
                    }
                }
            }
            Message::Response(_) => {}
        }
    }
    drop(connection);
    io.join().map_err(|e| fail(EXIT_IO, format!("lsp: {e}")))
}

/// The open documents, each analysed.
#[derive(Default)]
struct Server {
    docs: HashMap<String, Doc>,
    /// Mesh files read and cut, kept between checks: a scene importing a
    /// large mesh is not read again on every keystroke.
    meshes: cso::lang::check::MeshCache,
}

struct Doc {
    uri: lsp::Uri,
    analysis: Analysis,
    lines: Lines,
}

impl Server {
    /// A request's response; an error response for an unknown method, bad
    /// parameters or a panic while answering.
    fn answer(&mut self, req: Request) -> Response {
        let id = req.id.clone();
        let answer = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.dispatch(req)));
        match answer {
            Ok(Ok(value)) => Response::new_ok(id, value),
            Ok(Err((code, message))) => Response::new_err(id, code as i32, message),
            Err(_) => Response::new_err(
                id,
                ErrorCode::InternalError as i32,
                "cso lsp failed answering this request (a bug: please report it)".into(),
            ),
        }
    }

    fn dispatch(&mut self, req: Request) -> Result<serde_json::Value, (ErrorCode, String)> {
        use lsp::request::*;
        let json = |v: serde_json::Result<serde_json::Value>| {
            v.map_err(|e| (ErrorCode::InternalError, e.to_string()))
        };
        match req.method.as_str() {
            HoverRequest::METHOD => {
                let p: lsp::HoverParams = params(req)?;
                let (doc, offset) = self.at(&p.text_document_position_params)?;
                let hover = doc.analysis.hover(offset).map(|text| lsp::Hover {
                    contents: lsp::HoverContents::Markup(lsp::MarkupContent {
                        kind: lsp::MarkupKind::Markdown,
                        value: text,
                    }),
                    range: None,
                });
                json(serde_json::to_value(hover))
            }
            GotoDefinition::METHOD => {
                let p: lsp::GotoDefinitionParams = params(req)?;
                let (doc, offset) = self.at(&p.text_document_position_params)?;
                let loc = doc
                    .analysis
                    .definition(offset)
                    .map(|d| lsp::GotoDefinitionResponse::Scalar(doc.location(d.span)));
                json(serde_json::to_value(loc))
            }
            References::METHOD => {
                let p: lsp::ReferenceParams = params(req)?;
                let (doc, offset) = self.at(&p.text_document_position)?;
                let mut refs = doc.analysis.references(offset);
                if !p.context.include_declaration && !refs.is_empty() {
                    refs.remove(0);
                }
                let locs: Vec<lsp::Location> = refs.iter().map(|o| doc.location(o.span)).collect();
                json(serde_json::to_value(locs))
            }
            Completion::METHOD => {
                let p: lsp::CompletionParams = params(req)?;
                let (doc, offset) = self.at(&p.text_document_position)?;
                let items: Vec<lsp::CompletionItem> = doc
                    .analysis
                    .completions(offset)
                    .into_iter()
                    .map(|c| lsp::CompletionItem {
                        label: c.label,
                        kind: Some(match c.kind {
                            Kind::Keyword => lsp::CompletionItemKind::KEYWORD,
                            Kind::Field => lsp::CompletionItemKind::FIELD,
                            Kind::Face => lsp::CompletionItemKind::ENUM_MEMBER,
                            Kind::Unit => lsp::CompletionItemKind::UNIT,
                            Kind::Name => lsp::CompletionItemKind::VARIABLE,
                            Kind::Function => lsp::CompletionItemKind::FUNCTION,
                        }),
                        detail: Some(c.detail),
                        ..Default::default()
                    })
                    .collect();
                json(serde_json::to_value(lsp::CompletionResponse::Array(items)))
            }
            Formatting::METHOD => {
                let p: lsp::DocumentFormattingParams = params(req)?;
                let doc = self.doc(&p.text_document.uri)?;
                let src = &doc.analysis.src;
                // A file that does not parse is left as it is.
                let edits = match cso::lang::fmt::format(src) {
                    Ok(text) if text != *src => vec![lsp::TextEdit {
                        range: lsp::Range {
                            start: lsp::Position::new(0, 0),
                            end: doc.lines.position(src.len()),
                        },
                        new_text: text,
                    }],
                    _ => Vec::new(),
                };
                json(serde_json::to_value(edits))
            }
            DocumentSymbolRequest::METHOD => {
                let p: lsp::DocumentSymbolParams = params(req)?;
                let doc = self.doc(&p.text_document.uri)?;
                #[allow(deprecated)]
                let symbols: Vec<lsp::DocumentSymbol> = doc
                    .analysis
                    .symbols()
                    .into_iter()
                    .map(|s| lsp::DocumentSymbol {
                        name: s.name,
                        detail: Some(s.detail),
                        kind: match s.kind {
                            Some(NameKind::Let) => lsp::SymbolKind::CONSTANT,
                            Some(NameKind::Material) => lsp::SymbolKind::STRUCT,
                            Some(NameKind::Body) => lsp::SymbolKind::OBJECT,
                            Some(NameKind::Design) => lsp::SymbolKind::VARIABLE,
                            Some(NameKind::Probe) => lsp::SymbolKind::EVENT,
                            Some(_) => lsp::SymbolKind::INTERFACE,
                            None => lsp::SymbolKind::NAMESPACE,
                        },
                        tags: None,
                        deprecated: None,
                        range: doc.lines.range(s.span),
                        selection_range: doc.lines.range(s.name_span),
                        children: None,
                    })
                    .collect();
                json(serde_json::to_value(lsp::DocumentSymbolResponse::Nested(
                    symbols,
                )))
            }
            other => Err((
                ErrorCode::MethodNotFound,
                format!("cso lsp does not answer `{other}`"),
            )),
        }
    }

    fn doc(&self, uri: &lsp::Uri) -> Result<&Doc, (ErrorCode, String)> {
        self.docs.get(uri.as_str()).ok_or_else(|| {
            (
                ErrorCode::InvalidParams,
                format!("{} is not open", uri.as_str()),
            )
        })
    }

    fn at(
        &self,
        p: &lsp::TextDocumentPositionParams,
    ) -> Result<(&Doc, usize), (ErrorCode, String)> {
        let doc = self.doc(&p.text_document.uri)?;
        Ok((doc, doc.lines.offset(p.position)))
    }

    /// Open, change, close: the document analysed again and its diagnostics
    /// published.
    fn notified(&mut self, n: Notification) -> Vec<Notification> {
        use lsp::notification::*;
        let (uri, text) = match n.method.as_str() {
            DidOpenTextDocument::METHOD => {
                let Ok(p) = serde_json::from_value::<lsp::DidOpenTextDocumentParams>(n.params)
                else {
                    return Vec::new();
                };
                (p.text_document.uri, p.text_document.text)
            }
            DidChangeTextDocument::METHOD => {
                let Ok(p) = serde_json::from_value::<lsp::DidChangeTextDocumentParams>(n.params)
                else {
                    return Vec::new();
                };
                // Full synchronisation: the last change is the whole text.
                let Some(change) = p.content_changes.into_iter().next_back() else {
                    return Vec::new();
                };
                (p.text_document.uri, change.text)
            }
            DidCloseTextDocument::METHOD => {
                let Ok(p) = serde_json::from_value::<lsp::DidCloseTextDocumentParams>(n.params)
                else {
                    return Vec::new();
                };
                self.docs.remove(p.text_document.uri.as_str());
                return vec![publish(p.text_document.uri, Vec::new())];
            }
            _ => return Vec::new(),
        };
        let meshes = self.meshes.clone();
        let analysed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let opts = CheckOptions {
                base_dir: folder_of(&uri),
                mesh_cache: Some(meshes),
                ..CheckOptions::default()
            };
            Analysis::new(&text, &opts)
        }));
        let Ok(analysis) = analysed else {
            return Vec::new();
        };
        let lines = Lines::new(&analysis.src);
        let diagnostics = analysis
            .diagnostics
            .iter()
            .map(|d| diagnostic(d, &lines))
            .collect();
        self.docs.insert(
            uri.as_str().to_string(),
            Doc {
                uri: uri.clone(),
                analysis,
                lines,
            },
        );
        vec![publish(uri, diagnostics)]
    }
}

impl Doc {
    fn location(&self, span: Span) -> lsp::Location {
        lsp::Location {
            uri: self.uri.clone(),
            range: self.lines.range(span),
        }
    }
}

/// A request's parameters, or an InvalidParams error.
fn params<P: serde::de::DeserializeOwned>(req: Request) -> Result<P, (ErrorCode, String)> {
    serde_json::from_value(req.params).map_err(|e| (ErrorCode::InvalidParams, e.to_string()))
}

fn publish(uri: lsp::Uri, diagnostics: Vec<lsp::Diagnostic>) -> Notification {
    use lsp::notification::{Notification as _, PublishDiagnostics};
    let params = lsp::PublishDiagnosticsParams {
        uri,
        diagnostics,
        version: None,
    };
    Notification::new(
        PublishDiagnostics::METHOD.to_string(),
        serde_json::to_value(params).unwrap_or(serde_json::Value::Null),
    )
}

/// A checker diagnostic as the editor shows it: the primary label's range,
/// the message with the label and the help, the code, the severity.
fn diagnostic(d: &cso::lang::Diagnostic, lines: &Lines) -> lsp::Diagnostic {
    // A diagnostic about a `--set` value has no place in the file.
    let primary = d.labels.first().filter(|_| d.origin.is_none());
    let range = primary.map_or_else(lsp::Range::default, |l| lines.range(l.span));
    let mut message = d.message.clone();
    if let Some(l) = primary.filter(|l| !l.text.is_empty()) {
        message.push_str(&format!(" ({})", l.text));
    }
    if let Some(h) = &d.help {
        message.push_str(&format!("\nhelp: {h}"));
    }
    lsp::Diagnostic {
        range,
        severity: Some(if d.is_error() {
            lsp::DiagnosticSeverity::ERROR
        } else {
            lsp::DiagnosticSeverity::WARNING
        }),
        code: Some(lsp::NumberOrString::String(d.code.to_string())),
        source: Some("cso".into()),
        message,
        ..Default::default()
    }
}

/// The folder of a `file:` URI, for mesh paths relative to the scene.
fn folder_of(uri: &lsp::Uri) -> Option<std::path::PathBuf> {
    let s = uri.as_str().strip_prefix("file://")?;
    let mut bytes = Vec::with_capacity(s.len());
    let raw = s.as_bytes();
    let mut i = 0;
    while i < raw.len() {
        if raw[i] == b'%' && i + 2 < raw.len() {
            if let Ok(b) = u8::from_str_radix(&s[i + 1..i + 3], 16) {
                bytes.push(b);
                i += 3;
                continue;
            }
        }
        bytes.push(raw[i]);
        i += 1;
    }
    let path = std::path::PathBuf::from(String::from_utf8(bytes).ok()?);
    path.parent().map(std::path::Path::to_path_buf)
}

/// Byte offsets against LSP positions (line, UTF-16 column).
struct Lines {
    text: String,
    starts: Vec<usize>,
}

impl Lines {
    fn new(text: &str) -> Lines {
        let starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Lines {
            text: text.to_string(),
            starts,
        }
    }

    fn position(&self, offset: usize) -> lsp::Position {
        let offset = offset.min(self.text.len());
        let line = self
            .starts
            .partition_point(|&s| s <= offset)
            .saturating_sub(1);
        let start = self.starts[line];
        let col: usize = self
            .text
            .get(start..offset)
            .map_or(0, |s| s.chars().map(char::len_utf16).sum());
        lsp::Position::new(line as u32, col as u32)
    }

    fn offset(&self, p: lsp::Position) -> usize {
        let Some(&start) = self.starts.get(p.line as usize) else {
            return self.text.len();
        };
        let mut units = 0;
        for (i, c) in self.text[start..].char_indices() {
            if units >= p.character as usize || c == '\n' {
                return start + i;
            }
            units += c.len_utf16();
        }
        self.text.len()
    }

    fn range(&self, span: Span) -> lsp::Range {
        lsp::Range {
            start: self.position(span.start),
            end: self.position(span.end),
        }
    }
}
