//! Diagnostics: what went wrong in a source, where, and how to fix it.
//!
//! The library builds plain [`Diagnostic`] values (a code, a message, labelled spans,
//! a hint); [`render`] draws them rustc-style through miette with no colour at a
//! fixed width, so the output is the same on every terminal and in snapshots.

use super::ast::Span;
use miette::{GraphicalReportHandler, GraphicalTheme, LabeledSpan, NamedSource, SourceCode};
use std::fmt;

/// One labelled place in the source.
#[derive(Debug, Clone, PartialEq)]
pub struct Label {
    pub span: Span,
    pub text: String,
}

/// Whether a diagnostic stops the scene (an error) or only says something the
/// user should look at (a warning: the scene still checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    #[default]
    Error,
    Warning,
}

/// An error (or a warning) found in a source text.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostic {
    /// A stable code, e.g. `cso::unknown-name`.
    pub code: &'static str,
    /// An error (the default) or a warning.
    pub severity: Severity,
    /// One line: what is wrong.
    pub message: String,
    /// The first label is the primary one (where the error is).
    pub labels: Vec<Label>,
    /// How to fix it, when we know.
    pub help: Option<String>,
    /// The text the spans point into when it is not the file itself (a `--set` value).
    pub origin: Option<(String, String)>,
}

impl Diagnostic {
    pub fn new(code: &'static str, message: impl Into<String>) -> Self {
        Diagnostic {
            code,
            severity: Severity::Error,
            message: message.into(),
            labels: Vec::new(),
            help: None,
            origin: None,
        }
    }

    /// A warning: the scene still checks, but the user should look at this.
    pub fn warning(code: &'static str, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Warning,
            ..Diagnostic::new(code, message)
        }
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }

    /// Adds a labelled span (the first one added is the primary one).
    pub fn label(mut self, span: Span, text: impl Into<String>) -> Self {
        self.labels.push(Label {
            span,
            text: text.into(),
        });
        self
    }

    pub fn help(mut self, help: impl Into<String>) -> Self {
        self.help = Some(help.into());
        self
    }

    /// The diagnostic's spans point into `text`, shown under `name`.
    pub fn in_origin(mut self, name: impl Into<String>, text: impl Into<String>) -> Self {
        self.origin = Some((name.into(), text.into()));
        self
    }

    /// Where the diagnostic is (for sorting), or 0.
    pub fn offset(&self) -> usize {
        if self.origin.is_some() {
            return 0;
        }
        self.labels.first().map_or(0, |l| l.span.start)
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Diagnostic {}

/// A diagnostic tied to the source it points into, as miette wants it.
struct WithSource<'a> {
    diag: &'a Diagnostic,
    source: NamedSource<String>,
}

impl fmt::Debug for WithSource<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.diag, f)
    }
}

impl fmt::Display for WithSource<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.diag.message)
    }
}

impl std::error::Error for WithSource<'_> {}

impl miette::Diagnostic for WithSource<'_> {
    fn code<'b>(&'b self) -> Option<Box<dyn fmt::Display + 'b>> {
        Some(Box::new(self.diag.code))
    }

    fn severity(&self) -> Option<miette::Severity> {
        Some(match self.diag.severity {
            Severity::Error => miette::Severity::Error,
            Severity::Warning => miette::Severity::Warning,
        })
    }

    fn help<'b>(&'b self) -> Option<Box<dyn fmt::Display + 'b>> {
        self.diag
            .help
            .as_ref()
            .map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn SourceCode> {
        Some(&self.source)
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        let len = self.source.inner().len();
        let labels = self.diag.labels.iter().enumerate().map(move |(i, l)| {
            let start = l.span.start.min(len);
            let end = l.span.end.clamp(start, len);
            let text = (!l.text.is_empty()).then(|| l.text.clone());
            if i == 0 {
                LabeledSpan::new_primary_with_span(text, (start, end - start))
            } else {
                LabeledSpan::new_with_span(text, (start, end - start))
            }
        });
        Some(Box::new(labels))
    }
}

/// Width of rendered diagnostics, fixed so that output is the same everywhere.
pub const RENDER_WIDTH: usize = 100;

/// Renders diagnostics of the source `text` named `name`, rustc-style, no colour.
pub fn render(diags: &[Diagnostic], name: &str, text: &str) -> String {
    let handler = GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor())
        .with_width(RENDER_WIDTH)
        .with_links(false);
    let mut out = String::new();
    for diag in diags {
        let source = match &diag.origin {
            Some((n, t)) => NamedSource::new(n.clone(), t.clone()),
            None => NamedSource::new(name, text.to_string()),
        };
        let wrapped = WithSource { diag, source };
        // Writing to a String cannot fail; a formatter error would only drop this one.
        let _ = handler.render_report(&mut out, &wrapped);
    }
    out
}

/// A scene file's bytes as text, or a diagnostic at the first byte that is not
/// UTF-8, with line, column and the byte, and a lossy text to render it against
/// (its prefix up to that byte is the file's own, so the span is exact).
pub fn decode(bytes: Vec<u8>) -> Result<String, Box<(Diagnostic, String)>> {
    let e = match String::from_utf8(bytes) {
        Ok(s) => return Ok(s),
        Err(e) => e,
    };
    let at = e.utf8_error().valid_up_to();
    let byte = e.as_bytes().get(at).copied().unwrap_or(0);
    let text = String::from_utf8_lossy(e.as_bytes()).into_owned();
    let (line, column) = line_column(&text, at);
    let d = Diagnostic::new(
        "cso::encoding",
        format!("the file is not UTF-8: byte 0x{byte:02X} at line {line}, column {column}"),
    )
    .label(
        Span {
            start: at,
            end: at + char::REPLACEMENT_CHARACTER.len_utf8(),
        },
        format!("byte 0x{byte:02X} is not UTF-8"),
    )
    .help("save the file as UTF-8 (e.g. `iconv -f latin1 -t utf-8`); cso reads UTF-8 only");
    Err(Box::new((d, text)))
}

/// The 1-based line and column (in characters) of byte `offset` of `text`.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut at = offset.min(text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[start..].chars().count() + 1)
}

/// One labelled place of a diagnostic for programs: file, 1-based line and
/// column of both ends, byte offsets, and the label.
#[derive(Debug, Clone, serde::Serialize)]
pub struct JsonLabel {
    pub file: String,
    pub line: usize,
    pub column: usize,
    pub end_line: usize,
    pub end_column: usize,
    pub start: usize,
    pub end: usize,
    pub text: String,
}

/// A diagnostic as `cso compile --json` prints it (an editor or CI reads it).
#[derive(Debug, Clone, serde::Serialize)]
pub struct JsonDiagnostic {
    pub code: &'static str,
    pub severity: Severity,
    pub message: String,
    /// The first label is the primary one.
    pub labels: Vec<JsonLabel>,
    pub help: Option<String>,
}

/// Diagnostics of the source `text` named `name` for programs, with the
/// places resolved to lines and columns (a `--set` value is its own file).
pub fn to_json(diags: &[Diagnostic], name: &str, text: &str) -> Vec<JsonDiagnostic> {
    diags
        .iter()
        .map(|d| {
            let (file, src) = match &d.origin {
                Some((n, t)) => (n.as_str(), t.as_str()),
                None => (name, text),
            };
            let labels = d
                .labels
                .iter()
                .map(|l| {
                    let (line, column) = line_column(src, l.span.start);
                    let (end_line, end_column) = line_column(src, l.span.end);
                    JsonLabel {
                        file: file.to_string(),
                        line,
                        column,
                        end_line,
                        end_column,
                        start: l.span.start,
                        end: l.span.end,
                        text: l.text.clone(),
                    }
                })
                .collect();
            JsonDiagnostic {
                code: d.code,
                severity: d.severity,
                message: d.message.clone(),
                labels,
                help: d.help.clone(),
            }
        })
        .collect()
}

/// Sorts diagnostics by position (overrides first) and drops exact repeats.
pub fn sort(diags: &mut Vec<Diagnostic>) {
    diags.sort_by_key(|d| d.offset());
    diags.dedup();
}

/// Rounds to 6 significant digits (stable across machines).
pub fn round6(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    format!("{v:.5e}").parse().unwrap_or(v)
}

/// A number as a person reads it: `0.04`, `1000`, `2.1e11`, `1e-8` (6 digits at most).
pub fn num(v: f64) -> String {
    let r = round6(v);
    let a = r.abs();
    if r == 0.0 {
        "0".into()
    } else if !r.is_finite() || (1e-3..1e6).contains(&a) {
        format!("{r}")
    } else {
        format!("{r:e}")
    }
}
