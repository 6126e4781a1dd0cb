//! Text to syntax tree: the pest grammar in `grammar/cso.pest`, then a walk over
//! its pairs into [`ast`](super::ast) nodes with spans.
//!
//! Items are parsed one at a time so that one syntax error does not hide the next:
//! after an error the parser skips to the next line that starts an item outside any
//! braces and goes on.

use super::ast::*;
use super::diag::Diagnostic;
use pest::error::{ErrorVariant, InputLocation};
use pest::iterators::Pair;
use pest::Parser;

#[derive(pest_derive::Parser)]
#[grammar = "../grammar/cso.pest"]
pub(crate) struct CsoParser;

/// The words that start a top-level item.
pub const ITEM_KEYWORDS: &[&str] = &[
    "scene",
    "let",
    "material",
    "body",
    "obstacle",
    "design",
    "fix",
    "displace",
    "symmetry",
    "traction",
    "pressure",
    "gravity",
    "glue",
    "contact",
    "probe",
    "morph",
    "minimize",
    "subject",
    "solver",
    "sensitivity",
    "optimize",
];

/// Parses a whole file. Returns the items that parsed and a diagnostic for each
/// syntax error.
pub fn parse_file(src: &str) -> (File, Vec<Diagnostic>) {
    let mut file = File::default();
    let mut diags = Vec::new();
    let deep = deep_positions(src);
    let mut deep_next = 0;
    // Where the last item that parsed ends, to notice junk after it on its line.
    let mut last_end: Option<usize> = None;
    let mut pos = skip_blank(src, 0);
    while pos < src.len() {
        while deep_next < deep.len() && deep[deep_next] < pos {
            deep_next += 1;
        }
        if let Some(&at) = deep.get(deep_next) {
            let stop = resync(src, pos);
            if at < stop {
                diags.push(
                    Diagnostic::new(
                        "cso::too-deep",
                        format!("brackets nested more than {MAX_NESTING} deep"),
                    )
                    .label(Span::new(at, at + 1), "too deep here")
                    .help("split the expression with `let` constants"),
                );
                file.broken.extend(item_name(src, pos));
                pos = stop;
                continue;
            }
        }
        match CsoParser::parse(Rule::item, &src[pos..]) {
            Ok(mut pairs) => match pairs.next() {
                Some(pair) => {
                    let end = pos + pair.as_span().end();
                    match too_long(&pair, pos) {
                        Some(d) => {
                            diags.push(d);
                            file.broken.extend(item_name(src, pos));
                        }
                        None => file.items.push(item(pair, pos)),
                    }
                    last_end = Some(end);
                    pos = skip_blank(src, end.max(pos + 1));
                }
                None => break,
            },
            Err(err) => {
                diags.push(syntax_error(src, pos, &err));
                // Junk on the line of the previous item (`let w = 1.2.3`): that
                // item was cut short, so its meaning is not to be trusted either.
                if last_end.is_some_and(|e| !src[e..pos].contains('\n')) {
                    if let Some(prev) = file.items.pop() {
                        file.broken.extend(item_name(src, prev.span.start));
                    }
                }
                file.broken.extend(item_name(src, pos));
                last_end = None;
                pos = resync(src, pos);
            }
        }
    }
    (file, diags)
}

/// Brackets may nest this deep (the parser recurses once per level).
pub const MAX_NESTING: usize = 32;
/// Terms of one `+`/`*`/`&&` chain, and prefix/postfix operators on one operand.
pub const MAX_CHAIN: usize = 256;

/// Calls `f(position, byte)` for every bracket `( ) [ ] { }` in `src[from..to]`
/// outside comments and strings.
fn for_each_bracket(src: &str, from: usize, to: usize, mut f: impl FnMut(usize, u8)) {
    let b = src.as_bytes();
    let to = to.min(b.len());
    let mut pos = from;
    while pos < to {
        match b[pos] {
            b'#' => {
                while pos < b.len() && b[pos] != b'\n' {
                    pos += 1;
                }
            }
            b'"' => {
                pos += 1;
                while pos < b.len() && b[pos] != b'"' && b[pos] != b'\n' {
                    pos += 1;
                }
            }
            c @ (b'(' | b'[' | b'{' | b')' | b']' | b'}') => f(pos, c),
            _ => {}
        }
        pos += 1;
    }
}

/// Where brackets first nest deeper than [`MAX_NESTING`] (each time they do): the
/// items there are refused before parsing, because the parser recurses once per level.
fn deep_positions(src: &str) -> Vec<usize> {
    let mut depth = 0usize;
    let mut out = Vec::new();
    for_each_bracket(src, 0, src.len(), |pos, c| {
        if matches!(c, b'(' | b'[' | b'{') {
            depth += 1;
            if depth == MAX_NESTING + 1 {
                out.push(pos);
            }
        } else {
            depth = depth.saturating_sub(1);
        }
    });
    out
}

/// Refuses an item with an operator chain longer than [`MAX_CHAIN`] (the syntax
/// tree nests once per term, and everything after walks it recursively).
fn too_long(pair: &Pair<Rule>, offset: usize) -> Option<Diagnostic> {
    for p in pair.clone().into_inner().flatten() {
        let chain = matches!(
            p.as_rule(),
            Rule::or_expr
                | Rule::and_expr
                | Rule::add_expr
                | Rule::mul_expr
                | Rule::unary_expr
                | Rule::pow_expr
                | Rule::pow_operand
                | Rule::postfix_expr
        );
        if chain {
            let n = p.clone().into_inner().count();
            if n > 2 * MAX_CHAIN {
                return Some(
                    Diagnostic::new(
                        "cso::too-long",
                        format!("an expression of more than {MAX_CHAIN} terms"),
                    )
                    .label(span_of(&p, offset), format!("{} operators and operands", n))
                    .help("split the expression with `let` constants"),
                );
            }
        }
    }
    None
}

/// Parses a lone expression (the value of `--set NAME=VALUE`).
pub fn parse_expr(src: &str) -> Result<Expr, Box<Diagnostic>> {
    if let Some(&at) = deep_positions(src).first() {
        return Err(Box::new(
            Diagnostic::new(
                "cso::too-deep",
                format!("brackets nested more than {MAX_NESTING} deep"),
            )
            .label(Span::new(at, at + 1), "too deep here"),
        ));
    }
    let start = skip_blank(src, 0);
    let parsed = CsoParser::parse(Rule::expr, &src[start..]);
    match parsed {
        Ok(mut pairs) => match pairs.next() {
            Some(pair) => {
                if let Some(d) = too_long(&pair, start) {
                    return Err(Box::new(d));
                }
                let end = start + pair.as_span().end();
                let rest = skip_blank(src, end);
                if rest < src.len() {
                    let (found, span) = found_at(src, rest);
                    return Err(Box::new(
                        Diagnostic::new(
                            "cso::syntax",
                            format!("unexpected {found} after the value"),
                        )
                        .label(span, "the value should end here"),
                    ));
                }
                Ok(expr(pair, start))
            }
            None => Err(Box::new(
                Diagnostic::new("cso::syntax", "expected a value")
                    .label(Span::new(0, src.len()), ""),
            )),
        },
        Err(err) => Err(Box::new(syntax_error(src, start, &err))),
    }
}

/// The keyword and name of an item starting at `pos` (`body punch {` gives
/// `("body", Some("punch"))`), if it starts with a keyword.
fn item_name(src: &str, pos: usize) -> Option<(String, Option<String>)> {
    let mut words = src[pos..]
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty());
    let keyword = words.next()?;
    if !ITEM_KEYWORDS.contains(&keyword) {
        return None;
    }
    Some((keyword.to_string(), words.next().map(str::to_string)))
}

/// Skips blanks and comments.
fn skip_blank(src: &str, mut pos: usize) -> usize {
    let bytes = src.as_bytes();
    while pos < bytes.len() {
        match bytes[pos] {
            b' ' | b'\t' | b'\r' | b'\n' => pos += 1,
            b'#' => {
                while pos < bytes.len() && bytes[pos] != b'\n' {
                    pos += 1;
                }
            }
            _ => break,
        }
    }
    pos
}

/// After a syntax error in the item starting at `start`: the next line that begins
/// with an item keyword while no brace opened since `start` is still open.
fn resync(src: &str, start: usize) -> usize {
    let bytes = src.as_bytes();
    let mut depth: i64 = 0;
    let mut pos = start;
    let mut line_start = false;
    while pos < bytes.len() {
        let b = bytes[pos];
        if line_start && depth <= 0 {
            let word_end = src[pos..]
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .map_or(src.len(), |n| pos + n);
            if ITEM_KEYWORDS.contains(&&src[pos..word_end]) {
                return pos;
            }
        }
        match b {
            b'#' => {
                while pos < bytes.len() && bytes[pos] != b'\n' {
                    pos += 1;
                }
                continue;
            }
            b'{' => depth += 1,
            b'}' => depth -= 1,
            b'"' => {
                pos += 1;
                while pos < bytes.len() && bytes[pos] != b'"' && bytes[pos] != b'\n' {
                    pos += 1;
                }
            }
            _ => {}
        }
        if b == b'\n' {
            line_start = true;
        } else if !(b == b' ' || b == b'\t' || b == b'\r') {
            line_start = false;
        }
        pos += 1;
        if line_start {
            pos = skip_spaces(src, pos);
        }
    }
    src.len()
}

fn skip_spaces(src: &str, mut pos: usize) -> usize {
    let bytes = src.as_bytes();
    while pos < bytes.len() && (bytes[pos] == b' ' || bytes[pos] == b'\t' || bytes[pos] == b'\r') {
        pos += 1;
    }
    pos
}

/// What stands at `pos`, for "found ..." in a message, and its span.
fn found_at(src: &str, pos: usize) -> (String, Span) {
    let rest = &src[pos.min(src.len())..];
    let Some(c) = rest.chars().next() else {
        return ("end of file".to_string(), Span::new(src.len(), src.len()));
    };
    if c.is_ascii_alphanumeric() || c == '_' {
        let n = rest
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
            .unwrap_or(rest.len());
        let word = rest[..n].trim_end_matches('.');
        let kind = if c.is_ascii_digit() { "number" } else { "name" };
        (format!("{kind} `{word}`"), Span::new(pos, pos + word.len()))
    } else if c == '\n' || c == '\r' {
        ("end of line".to_string(), Span::new(pos, pos))
    } else {
        let two: String = rest.chars().take(2).collect();
        let tok = if ["..", "<=", ">=", "==", "!=", "&&", "||"].contains(&two.as_str()) {
            two
        } else {
            c.to_string()
        };
        (format!("`{tok}`"), Span::new(pos, pos + tok.len()))
    }
}

/// How a rule reads in "expected ..." (None: not worth mentioning).
fn rule_name(rule: Rule) -> Option<&'static str> {
    Some(match rule {
        Rule::item
        | Rule::let_item
        | Rule::gravity_item
        | Rule::subject_item
        | Rule::minimize_item
        | Rule::condition_item
        | Rule::block_item
        | Rule::block_kw
        | Rule::condition_kw
        | Rule::kw_let
        | Rule::kw_gravity
        | Rule::kw_subject
        | Rule::kw_minimize => {
            "an item (`scene`, `let`, `material`, `body`, `fix`, `contact`, ...)"
        }
        Rule::kw_to => "`to`",
        Rule::ident => "a name",
        Rule::assign => "`=`",
        Rule::block_body | Rule::lbrace => "`{`",
        Rule::rbrace => "`}`",
        Rule::field => "a field `NAME = VALUE`",
        Rule::value | Rule::range | Rule::grid => "a value",
        Rule::expr
        | Rule::or_expr
        | Rule::and_expr
        | Rule::cmp_expr
        | Rule::add_expr
        | Rule::mul_expr
        | Rule::unary_expr
        | Rule::pow_expr
        | Rule::pow_operand
        | Rule::postfix_expr
        | Rule::paren_or_vector
        | Rule::list
        | Rule::quantity
        | Rule::number
        | Rule::string => "an expression",
        Rule::op_or
        | Rule::op_and
        | Rule::op_cmp
        | Rule::op_add
        | Rule::op_sub
        | Rule::op_mul
        | Rule::op_div
        | Rule::op_pow
        | Rule::op_neg
        | Rule::op_not => "an operator",
        Rule::member | Rule::dot => "`.`",
        Rule::index | Rule::lbracket => "`[`",
        Rule::call_args | Rule::lparen => "`(`",
        Rule::rparen => "`)`",
        Rule::rbracket => "`]`",
        Rule::comma => "`,`",
        Rule::dotdot => "`..`",
        Rule::grid_x => "`x`",
        Rule::grid_atom => "a count",
        Rule::unit | Rule::unit_term | Rule::unit_name | Rule::unknown_unit => "a unit",
        Rule::unit_power => "an integer power",
        Rule::unit_op => "`*` or `/`",
        Rule::string_inner => "the rest of the string",
        _ => return None,
    })
}

fn syntax_error(src: &str, offset: usize, err: &pest::error::Error<Rule>) -> Diagnostic {
    let at = offset
        + match err.location {
            InputLocation::Pos(p) => p,
            InputLocation::Span((s, _)) => s,
        };
    if let Some(d) = malformed_number(src, at) {
        return d;
    }
    let (found, span) = found_at(src, at);
    if src[at.min(src.len())..].starts_with('"')
        && !src[at + 1..].lines().next().unwrap_or("").contains('"')
    {
        return Diagnostic::new("cso::syntax", "unterminated string")
            .label(
                Span::new(at, at + 1),
                "this string is not closed on its line",
            )
            .help("a string must end with `\"` on the same line");
    }
    let mut expected: Vec<&str> = match &err.variant {
        ErrorVariant::ParsingError { positives, .. } => {
            positives.iter().filter_map(|r| rule_name(*r)).collect()
        }
        ErrorVariant::CustomError { .. } => Vec::new(),
    };
    // Operators are always possible after an expression; list them last, once.
    expected.sort_by_key(|e| (e.starts_with("an operator"), *e));
    expected.dedup();
    let open = unclosed(src, offset, at);
    // The error sits on a line that starts a new item while a `{` is still open:
    // the block before it was not closed.
    let line_start = src[..at].rfind('\n').map_or(0, |n| n + 1);
    let indent = src[line_start..].len() - src[line_start..].trim_start().len();
    let first_word: String = src[line_start + indent..]
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    if let Some(&brace) = open.iter().rev().find(|&&p| src.as_bytes()[p] == b'{') {
        if ITEM_KEYWORDS.contains(&first_word.as_str()) && line_start > brace {
            let word = line_start + indent;
            let before = src[..line_start].trim_end().len();
            return Diagnostic::new(
                "cso::unclosed",
                "a block is not closed before the next item",
            )
            .label(Span::new(brace, brace + 1), "this `{` is not closed")
            .label(
                Span::new(word, word + first_word.len()),
                "the next item starts here",
            )
            .help(format!(
                "add `}}` at the end of line {}",
                src[..before].matches('\n').count() + 1
            ));
        }
    }
    // A word where an item should start: a misspelt keyword, most likely.
    if expected.first().is_some_and(|e| e.starts_with("an item")) {
        if let Some(word) = found
            .strip_prefix("name `")
            .and_then(|w| w.strip_suffix('`'))
        {
            let help = super::suggest::did_you_mean(word, ITEM_KEYWORDS.iter().copied())
                .unwrap_or_else(|| {
                    format!(
                        "items start with {}",
                        ITEM_KEYWORDS
                            .iter()
                            .map(|k| format!("`{k}`"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                });
            return Diagnostic::new("cso::syntax", format!("unknown item `{word}`"))
                .label(span, "not an item keyword")
                .help(help);
        }
        if found == "`}`" {
            return Diagnostic::new("cso::syntax", "a `}` with no open block")
                .label(span, "nothing to close here")
                .help("remove this `}`, or the `}` before it that closed the block too early");
        }
    }
    // The innermost unclosed `(` or `[` opened on an earlier line: that is the error.
    if let Some(&p) = open.last().filter(|&&p| src.as_bytes()[p] != b'{') {
        if src[p..at].contains('\n') {
            let c = src[p..].chars().next().unwrap_or('(');
            let close = if c == '(' { ')' } else { ']' };
            return Diagnostic::new("cso::unclosed", format!("unclosed `{c}`"))
                .label(Span::new(p, p + 1), format!("this `{c}` is not closed"))
                .label(span, format!("expected `{close}` before this"))
                .help(format!("add `{close}` where the expression ends"));
        }
    }
    let what = match expected.len() {
        0 => "unexpected input".to_string(),
        1 => format!("expected {}", expected[0]),
        n => format!(
            "expected {} or {}",
            expected[..n - 1].join(", "),
            expected[n - 1]
        ),
    };
    let label = match expected.len() {
        1 => format!("expected {}", expected[0]),
        2 => format!("expected {} or {}", expected[0], expected[1]),
        _ => "not expected here".to_string(),
    };
    let mut diag =
        Diagnostic::new("cso::syntax", format!("{what}, found {found}")).label(span, label);
    if let Some(&p) = open.last().filter(|&&p| src.as_bytes()[p] != b'{') {
        let c = src[p..].chars().next().unwrap_or('(');
        diag = diag.label(Span::new(p, p + 1), format!("this `{c}` is not closed"));
    }
    if let Some(hint) = syntax_hint(src, at, &expected) {
        diag = diag.help(hint);
    }
    diag
}

/// `1.2.3`: a number with a second decimal point, reported as one thing.
fn malformed_number(src: &str, at: usize) -> Option<Diagnostic> {
    let b = src.as_bytes();
    let digit = |i: usize| b.get(i).is_some_and(u8::is_ascii_digit);
    if b.get(at) != Some(&b'.') || !(at > 0 && digit(at - 1)) || !digit(at + 1) {
        return None;
    }
    let numberish = |c: u8| c.is_ascii_digit() || c == b'.';
    let start = src[..at]
        .bytes()
        .rposition(|c| !numberish(c))
        .map_or(0, |p| p + 1);
    let end = at
        + src[at..]
            .bytes()
            .position(|c| !numberish(c))
            .unwrap_or(src.len() - at);
    let text = &src[start..end];
    Some(
        Diagnostic::new("cso::syntax", format!("malformed number `{text}`"))
            .label(
                Span::new(start, end),
                "a number has at most one decimal point",
            )
            .help("write numbers like `12`, `0.5`, `1e-3`, `2.1E11`"),
    )
}

/// Brackets opened between `from` and `to` and not closed by `to`, innermost last.
fn unclosed(src: &str, from: usize, to: usize) -> Vec<usize> {
    let mut stack = Vec::new();
    for_each_bracket(src, from, to, |pos, c| {
        if matches!(c, b'(' | b'[' | b'{') {
            stack.push(pos);
        } else {
            stack.pop();
        }
    });
    stack
}

/// A hint for the syntax errors people make most.
fn syntax_hint(src: &str, at: usize, expected: &[&str]) -> Option<String> {
    let rest = &src[at.min(src.len())..];
    let prev = src[..at.min(src.len())].chars().next_back();
    if rest.starts_with(':') {
        return Some("fields are written `NAME = VALUE`, not `NAME: VALUE`".into());
    }
    if rest.starts_with(';') {
        return Some("separate fields with `,` or a newline; `;` is not used".into());
    }
    if rest.starts_with("**") || (rest.starts_with('*') && prev == Some('*')) {
        return Some("powers are written `a^b`".into());
    }
    if rest.is_empty() && expected.contains(&"`}`") {
        return Some("a block opened with `{` was not closed".into());
    }
    if rest.starts_with('"') {
        return Some("a string must end with `\"` on the same line".into());
    }
    if expected.contains(&"`=`") {
        return Some("fields and constants are written `NAME = VALUE`".into());
    }
    None
}

// ---------------------------------------------------------------- pairs to AST

fn span_of(pair: &Pair<Rule>, offset: usize) -> Span {
    let s = pair.as_span();
    Span::new(offset + s.start(), offset + s.end())
}

fn ident(pair: Pair<Rule>, offset: usize) -> Ident {
    Ident {
        span: span_of(&pair, offset),
        name: pair.as_str().to_string(),
    }
}

/// Is this pair punctuation that carries no meaning once parsed?
fn is_punct(rule: Rule) -> bool {
    matches!(
        rule,
        Rule::lbrace
            | Rule::rbrace
            | Rule::lparen
            | Rule::rparen
            | Rule::lbracket
            | Rule::rbracket
            | Rule::comma
            | Rule::dotdot
            | Rule::dot
            | Rule::assign
            | Rule::grid_x
            | Rule::kw_to
    )
}

fn inner(pair: Pair<Rule>) -> impl Iterator<Item = Pair<Rule>> {
    pair.into_inner().filter(|p| !is_punct(p.as_rule()))
}

fn item(pair: Pair<Rule>, offset: usize) -> Item {
    // `item` wraps exactly one alternative.
    let span = span_of(&pair, offset);
    let alt = match pair.into_inner().next() {
        Some(p) => p,
        None => unreachable_item(),
    };
    let rule = alt.as_rule();
    let mut parts = inner(alt);
    let kind = match rule {
        Rule::let_item => {
            let _kw = parts.next();
            let name = ident(next(&mut parts), offset);
            let value = expr(next(&mut parts), offset);
            ItemKind::Let { name, value }
        }
        Rule::gravity_item => {
            let _kw = parts.next();
            ItemKind::Gravity {
                value: expr(next(&mut parts), offset),
            }
        }
        Rule::minimize_item => {
            let _kw = parts.next();
            ItemKind::Minimize {
                expr: expr(next(&mut parts), offset),
            }
        }
        Rule::subject_item => {
            let _kw = parts.next();
            ItemKind::SubjectTo {
                expr: expr(next(&mut parts), offset),
            }
        }
        Rule::condition_item => {
            let keyword = ident(next(&mut parts), offset);
            let selection = expr(next(&mut parts), offset);
            let mut fields = None;
            let mut value = None;
            for p in parts {
                match p.as_rule() {
                    Rule::block_body => fields = Some(block(p, offset)),
                    _ => value = Some(expr(p, offset)),
                }
            }
            ItemKind::Condition {
                keyword,
                selection,
                fields,
                value,
            }
        }
        _ => {
            let keyword = ident(next(&mut parts), offset);
            let mut name = None;
            let mut size = None;
            let mut body = Block {
                fields: Vec::new(),
                span,
            };
            for p in parts {
                match p.as_rule() {
                    Rule::ident => name = Some(ident(p, offset)),
                    Rule::expr => size = Some(expr(p, offset)),
                    _ => body = block(p, offset),
                }
            }
            ItemKind::Block {
                keyword,
                name,
                size,
                body,
            }
        }
    };
    Item { kind, span }
}

/// The grammar guarantees the shape of every pair we walk; this is only reached if
/// the grammar and this walk disagree, which the tests would show.
#[cold]
fn unreachable_item() -> ! {
    unreachable!("grammar and syntax-tree walk disagree")
}

fn next<'a>(parts: &mut impl Iterator<Item = Pair<'a, Rule>>) -> Pair<'a, Rule> {
    match parts.next() {
        Some(p) => p,
        None => unreachable_item(),
    }
}

fn block(pair: Pair<Rule>, offset: usize) -> Block {
    let span = span_of(&pair, offset);
    let fields = inner(pair)
        .map(|f| {
            let span = span_of(&f, offset);
            let mut parts = inner(f);
            let name = ident(next(&mut parts), offset);
            let value = parts.next().map(|v| value(v, offset));
            Field { name, value, span }
        })
        .collect();
    Block { fields, span }
}

fn value(pair: Pair<Rule>, offset: usize) -> Value {
    let v = next(&mut pair.into_inner());
    match v.as_rule() {
        Rule::range => {
            let mut parts = inner(v);
            let a = expr(next(&mut parts), offset);
            let b = expr(next(&mut parts), offset);
            Value::Range(a, b)
        }
        Rule::grid => Value::Grid(inner(v).map(|p| grid_atom(p, offset)).collect()),
        _ => Value::Expr(expr(v, offset)),
    }
}

fn expr(pair: Pair<Rule>, offset: usize) -> Expr {
    match pair.as_rule() {
        Rule::expr => expr(next(&mut pair.into_inner()), offset),
        Rule::or_expr | Rule::and_expr | Rule::cmp_expr | Rule::add_expr | Rule::mul_expr => {
            let mut parts = pair.into_inner();
            let mut lhs = expr(next(&mut parts), offset);
            while let Some(op) = parts.next() {
                let rhs = expr(next(&mut parts), offset);
                let op = binop(op.as_str());
                let span = lhs.span.to(rhs.span);
                lhs = Expr {
                    kind: ExprKind::Binary(op, Box::new(lhs), Box::new(rhs)),
                    span,
                };
            }
            lhs
        }
        Rule::unary_expr => {
            let parts: Vec<_> = pair.into_inner().collect();
            let (last, ops) = match parts.split_last() {
                Some(x) => x,
                None => unreachable_item(),
            };
            let mut e = expr(last.clone(), offset);
            for op in ops.iter().rev() {
                e = prefixed(op, e, offset);
            }
            e
        }
        Rule::pow_expr => {
            // Operands with their prefix operators; `-a ^ b` never reaches here
            // (unary_expr takes the first operand's prefix), `a ^ -b ^ c` does.
            let mut operands: Vec<(Vec<Pair<Rule>>, Expr)> = Vec::new();
            for p in pair.into_inner() {
                match p.as_rule() {
                    Rule::op_pow => {}
                    Rule::pow_operand => {
                        let mut parts: Vec<Pair<Rule>> = p.into_inner().collect();
                        let base = match parts.pop() {
                            Some(b) => expr(b, offset),
                            None => unreachable_item(),
                        };
                        operands.push((parts, base));
                    }
                    _ => operands.push((Vec::new(), expr(p, offset))),
                }
            }
            let mut acc: Option<Expr> = None;
            while let Some((prefix, base)) = operands.pop() {
                let mut e = match acc.take() {
                    Some(exp) => {
                        let span = base.span.to(exp.span);
                        Expr {
                            kind: ExprKind::Binary(BinOp::Pow, Box::new(base), Box::new(exp)),
                            span,
                        }
                    }
                    None => base,
                };
                for op in prefix.iter().rev() {
                    e = prefixed(op, e, offset);
                }
                acc = Some(e);
            }
            match acc {
                Some(e) => e,
                None => unreachable_item(),
            }
        }
        Rule::postfix_expr => {
            let mut parts = pair.into_inner();
            let mut e = atom(next(&mut parts), offset);
            for post in parts {
                let end = span_of(&post, offset);
                let span = e.span.to(end);
                let kind = match post.as_rule() {
                    Rule::member => ExprKind::Member {
                        base: Box::new(e),
                        name: ident(next(&mut inner(post)), offset),
                    },
                    Rule::index => ExprKind::Index {
                        base: Box::new(e),
                        index: Box::new(expr(next(&mut inner(post)), offset)),
                    },
                    _ => ExprKind::Call {
                        func: Box::new(e),
                        args: inner(post).map(|a| expr(a, offset)).collect(),
                    },
                };
                e = Expr { kind, span };
            }
            e
        }
        _ => atom(pair, offset),
    }
}

/// One count of a grid, with its sign if written.
fn grid_atom(pair: Pair<Rule>, offset: usize) -> Expr {
    let mut parts: Vec<Pair<Rule>> = pair.into_inner().collect();
    let base = match parts.pop() {
        Some(p) => atom(p, offset),
        None => unreachable_item(),
    };
    match parts.first() {
        Some(op) => prefixed(op, base, offset),
        None => base,
    }
}

/// `-e` or `!e`.
fn prefixed(op: &Pair<Rule>, e: Expr, offset: usize) -> Expr {
    let un = if op.as_rule() == Rule::op_not {
        UnOp::Not
    } else {
        UnOp::Neg
    };
    let span = span_of(op, offset).to(e.span);
    Expr {
        kind: ExprKind::Unary(un, Box::new(e)),
        span,
    }
}

fn atom(pair: Pair<Rule>, offset: usize) -> Expr {
    let span = span_of(&pair, offset);
    let kind = match pair.as_rule() {
        Rule::quantity => {
            let mut parts = pair.into_inner();
            let num = next(&mut parts);
            let value = num.as_str().parse::<f64>().unwrap_or(f64::NAN);
            let unit = parts.next().map(|u| unit(u, offset));
            ExprKind::Number { value, unit }
        }
        Rule::number => ExprKind::Number {
            value: pair.as_str().parse::<f64>().unwrap_or(f64::NAN),
            unit: None,
        },
        Rule::ident => ExprKind::Name(pair.as_str().to_string()),
        Rule::string => ExprKind::Str(
            pair.into_inner()
                .next()
                .map_or(String::new(), |p| p.as_str().to_string()),
        ),
        Rule::paren_or_vector => {
            let mut items: Vec<Expr> = inner(pair).map(|p| expr(p, offset)).collect();
            // `(e)` is a parenthesised expression; two or more entries make a vector.
            if items.len() == 1 {
                let mut e = items.remove(0);
                e.span = span;
                return e;
            }
            ExprKind::Vector(items)
        }
        Rule::list => ExprKind::List(inner(pair).map(|p| expr(p, offset)).collect()),
        _ => return expr(pair, offset),
    };
    Expr { kind, span }
}

fn unit(pair: Pair<Rule>, offset: usize) -> UnitExpr {
    let span = span_of(&pair, offset);
    if pair.as_rule() == Rule::unknown_unit {
        // The checker refuses it by name, with the nearest known units.
        return UnitExpr {
            factors: vec![(pair.as_str().to_string(), 1)],
            span,
        };
    }
    let mut factors = Vec::new();
    let mut sign = 1;
    for p in pair.into_inner() {
        match p.as_rule() {
            Rule::unit_op => sign = if p.as_str() == "/" { -1 } else { 1 },
            Rule::unit_term => {
                let mut parts = p.into_inner();
                let name = next(&mut parts).as_str().to_string();
                let power = parts
                    .next()
                    .map_or(1, |q| q.as_str().parse::<i32>().unwrap_or(i32::MAX));
                factors.push((name, sign * power));
            }
            _ => {}
        }
    }
    UnitExpr { factors, span }
}

fn binop(s: &str) -> BinOp {
    match s {
        "+" => BinOp::Add,
        "-" => BinOp::Sub,
        "*" => BinOp::Mul,
        "/" => BinOp::Div,
        "^" => BinOp::Pow,
        "<" => BinOp::Lt,
        "<=" => BinOp::Le,
        ">" => BinOp::Gt,
        ">=" => BinOp::Ge,
        "==" => BinOp::Eq,
        "!=" => BinOp::Ne,
        "&&" => BinOp::And,
        _ => BinOp::Or,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn examples_parse() {
        for entry in std::fs::read_dir("examples").unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_none_or(|e| e != "cso") {
                continue; // meshes and their scripts
            }
            let src = std::fs::read_to_string(&path).unwrap();
            let (file, diags) = parse_file(&src);
            assert!(diags.is_empty(), "{}: {:?}", path.display(), diags);
            assert!(!file.items.is_empty());
        }
    }
}
