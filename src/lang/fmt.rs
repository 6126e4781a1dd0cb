//! `cso fmt`: one canonical layout of a `.cso` file.
//!
//! The formatter rewrites whitespace only: it walks the parse tree's tokens
//! in order and joins them with canonical spacing, so the token sequence, and
//! with it the meaning, cannot change. The layout:
//!
//! - items in file order, one per line; a blank line between two items where
//!   the source had at least one (never two in a row), none where it had none;
//! - a block on one line, `KEYWORD NAME { field = value, field = value }`, where
//!   that fits in [`WIDTH`] columns and it holds no comment; otherwise one field
//!   per line, indented by two spaces, without commas, the closing `}` on a
//!   line of its own (blank lines between fields kept, one at most);
//! - `=`, `..`, `+ - * /`, comparisons, `&&`, `||` spaced; `^` and the member
//!   dot unspaced; `, ` between list entries, arguments and vector components;
//!   no space inside brackets; a unit after its number with one space
//!   (`210 GPa`, `5 kN/m`), the unit itself unspaced;
//! - comments kept: a comment on its own line stays on its own line before
//!   what followed it, at that place's indentation; a comment after code stays
//!   at the end of that line, two spaces after it. A comment inside an
//!   expression moves to the end of the line the expression ends on.
//!
//! Long expressions are not wrapped. A file with syntax errors is not
//! formatted (the errors are returned).

use super::diag::Diagnostic;
use super::parse::{parse_file, CsoParser, Rule};
use pest::iterators::Pair;
use pest::Parser;

/// Blocks longer than this go one field per line.
pub const WIDTH: usize = 120;

/// How a token is spaced against its neighbours.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A name, keyword, number (with its unit) or string.
    Word,
    /// A name that a call's `(` or an index's `[` may follow unspaced.
    Name,
    /// Spaced on both sides: `=`, `..`, `+`, `-`, `*`, `/`, comparisons, `&&`, `||`.
    Binary,
    /// `^`: unspaced.
    Pow,
    /// `*` or `/` written without spaces (`2*x`): kept so.
    Tight,
    /// Unary `-` and `!`: attached to what follows.
    Unary,
    Open,
    Close,
    Comma,
    /// The member dot: unspaced.
    Dot,
}

#[derive(Debug, Clone)]
struct Token {
    kind: Kind,
    text: String,
    start: usize,
    end: usize,
}

/// A field of a block: its tokens (comma left out).
#[derive(Debug, Clone)]
struct Field {
    tokens: Vec<Token>,
}

/// What an item is made of: tokens, and at most one block between them.
#[derive(Debug, Clone)]
enum Part {
    Token(Token),
    Block {
        fields: Vec<Field>,
        open: usize,
        close: usize,
    },
}

/// Formats a whole file. `Err`: the file has syntax errors (formatting it
/// could only guess), with their diagnostics.
pub fn format(src: &str) -> Result<String, Vec<Diagnostic>> {
    let (file, diags) = parse_file(src);
    if !diags.is_empty() {
        return Err(diags);
    }
    let mut out = Out::new(src);
    let mut pos = 0;
    for item in &file.items {
        let pair = CsoParser::parse(Rule::item, &src[item.span.start..])
            .ok()
            .and_then(|mut p| p.next());
        let Some(pair) = pair else {
            // parse_file parsed it: it parses again. Keep its text if not.
            out.gap(pos, item.span.start, 0);
            out.line(0, &src[item.span.start..item.span.end]);
            pos = item.span.end;
            continue;
        };
        let parts = parts(pair, item.span.start);
        out.gap(pos, item.span.start, 0);
        out.item(&parts);
        // The item's span runs on over the blanks and comments after it:
        // they belong to the next gap.
        pos = parts
            .iter()
            .map(|p| match p {
                Part::Token(t) => t.end,
                Part::Block { close, .. } => *close,
            })
            .max()
            .unwrap_or(item.span.end);
    }
    out.gap(pos, src.len(), 0);
    Ok(out.finish())
}

/// The parts of an item: its tokens in order, its block as fields.
fn parts(pair: Pair<Rule>, offset: usize) -> Vec<Part> {
    let mut out = Vec::new();
    collect(pair, offset, &mut out);
    out
}

fn collect(pair: Pair<Rule>, offset: usize, out: &mut Vec<Part>) {
    let span = pair.as_span();
    let (start, end) = (offset + span.start(), offset + span.end());
    let token = |kind: Kind, text: String| {
        Part::Token(Token {
            kind,
            text,
            start,
            end,
        })
    };
    match pair.as_rule() {
        Rule::block_body => {
            let mut fields = Vec::new();
            for p in pair.into_inner() {
                if p.as_rule() == Rule::field {
                    let mut parts = Vec::new();
                    collect(p, offset, &mut parts);
                    let tokens = parts
                        .into_iter()
                        .filter_map(|p| match p {
                            Part::Token(t) => Some(t),
                            Part::Block { .. } => None,
                        })
                        .collect();
                    fields.push(Field { tokens });
                }
            }
            out.push(Part::Block {
                fields,
                open: start,
                close: end,
            });
        }
        Rule::quantity => out.push(token(Kind::Word, quantity(pair))),
        Rule::string | Rule::number => out.push(token(Kind::Word, pair.as_str().to_string())),
        Rule::ident => out.push(token(Kind::Name, pair.as_str().to_string())),
        Rule::kw_let
        | Rule::kw_gravity
        | Rule::kw_subject
        | Rule::kw_to
        | Rule::kw_minimize
        | Rule::condition_kw
        | Rule::block_kw
        | Rule::grid_x => out.push(token(Kind::Word, pair.as_str().to_string())),
        Rule::assign
        | Rule::dotdot
        | Rule::op_or
        | Rule::op_and
        | Rule::op_cmp
        | Rule::op_add
        | Rule::op_sub
        | Rule::op_mul
        | Rule::op_div => {
            let input = pair.get_input().as_bytes();
            let blank = |i: Option<&u8>| i.is_some_and(|b| b.is_ascii_whitespace());
            let spaced = blank(span.start().checked_sub(1).and_then(|i| input.get(i)))
                || blank(input.get(span.end()));
            let is_product = matches!(pair.as_rule(), Rule::op_mul | Rule::op_div);
            let kind = if is_product && !spaced {
                Kind::Tight
            } else {
                Kind::Binary
            };
            out.push(token(kind, pair.as_str().to_string()))
        }
        Rule::op_pow => out.push(token(Kind::Pow, "^".into())),
        Rule::op_neg | Rule::op_not => out.push(token(Kind::Unary, pair.as_str().to_string())),
        Rule::lparen | Rule::lbracket | Rule::lbrace => {
            out.push(token(Kind::Open, pair.as_str().to_string()))
        }
        Rule::rparen | Rule::rbracket | Rule::rbrace => {
            out.push(token(Kind::Close, pair.as_str().to_string()))
        }
        Rule::comma => out.push(token(Kind::Comma, ",".into())),
        Rule::dot => out.push(token(Kind::Dot, ".".into())),
        _ => {
            for p in pair.into_inner() {
                collect(p, offset, out);
            }
        }
    }
}

/// A number and its unit: one space between, none inside the unit
/// (`5 kN / m` is `5 kN/m`).
fn quantity(pair: Pair<Rule>) -> String {
    let mut number = String::new();
    let mut unit = String::new();
    for p in pair.into_inner() {
        match p.as_rule() {
            Rule::number => number = p.as_str().to_string(),
            _ => unit = p.as_str().split_whitespace().collect(),
        }
    }
    if unit.is_empty() {
        number
    } else {
        format!("{number} {unit}")
    }
}

/// Tokens joined with canonical spacing.
fn join(tokens: &[Token]) -> String {
    let mut s = String::new();
    let mut prev: Option<Kind> = None;
    for t in tokens {
        if let Some(p) = prev {
            if spaced(p, t) {
                s.push(' ');
            }
        }
        s.push_str(&t.text);
        prev = Some(t.kind);
    }
    s
}

/// Is there a space between a token of kind `prev` and `t`?
fn spaced(prev: Kind, t: &Token) -> bool {
    use Kind::*;
    match (prev, t.kind) {
        (_, Comma) | (_, Close) | (_, Pow) | (_, Dot) | (_, Tight) => false,
        (Open | Unary | Pow | Dot | Tight, _) => false,
        // A call `f(` or an index `a[`; a block's `{` is spaced.
        (Name, Open) => t.text == "{",
        (Close, Open) => t.text == "{",
        (Binary, _) | (_, Binary) => true,
        (Comma, _) => true,
        _ => true,
    }
}

/// The formatted text being written, with the source to take comments from.
struct Out<'a> {
    src: &'a str,
    text: String,
    /// A blank line is due before the next line written.
    blank: bool,
    /// Lines that end in a comment after code: (line number, code length,
    /// the comment's column in the source).
    trailing: Vec<(usize, usize, usize)>,
}

impl<'a> Out<'a> {
    fn new(src: &'a str) -> Self {
        Out {
            src,
            text: String::new(),
            blank: false,
            trailing: Vec::new(),
        }
    }

    fn line(&mut self, indent: usize, s: &str) {
        if self.blank && !self.text.is_empty() {
            self.text.push('\n');
        }
        self.blank = false;
        self.text.push_str(&" ".repeat(indent));
        self.text.push_str(s);
        self.text.push('\n');
    }

    /// The comments and blank lines of `src[from..to]` (whitespace, commas
    /// and comments only): a comment after code on the same line goes at the
    /// end of the last line written; the others on lines of their own, a blank
    /// line before one where the source had one.
    fn gap(&mut self, from: usize, to: usize, indent: usize) {
        let gap = &self.src[from..to];
        let mut after_code = from > 0;
        let mut newlines = 0;
        let mut rest = gap;
        while let Some(hash) = rest.find('#') {
            newlines += rest[..hash].matches('\n').count();
            let end = rest[hash..].find('\n').map_or(rest.len(), |e| hash + e);
            let comment = rest[hash..end].trim_end();
            if after_code && newlines == 0 && !self.text.is_empty() {
                let at = to - rest.len() + hash;
                self.trailing(comment, at);
            } else {
                if newlines >= 2 {
                    self.blank = true;
                }
                self.line(indent, comment);
            }
            after_code = false;
            newlines = 0;
            rest = &rest[end..];
        }
        newlines += rest.matches('\n').count();
        if newlines >= 2 && !self.text.is_empty() {
            self.blank = true;
        }
    }

    /// `  # comment` at the end of the last line written.
    fn trailing(&mut self, comment: &str, at: usize) {
        if self.text.ends_with('\n') {
            self.text.pop();
        }
        let line = self.text.matches('\n').count();
        let code = self.text.len() - self.text.rfind('\n').map_or(0, |i| i + 1);
        let column = at - self.src[..at].rfind('\n').map_or(0, |i| i + 1);
        self.trailing.push((line, code, column));
        self.text.push_str("  ");
        self.text.push_str(comment);
        self.text.push('\n');
    }

    /// Is there a comment between any two of these spans (in order)?
    fn commented(&self, spans: &[(usize, usize)]) -> bool {
        spans
            .windows(2)
            .any(|w| self.src[w[0].1..w[1].0].contains('#'))
    }

    /// One item: on one line, or its block one field per line.
    fn item(&mut self, parts: &[Part]) {
        let tokens = |ps: &[Part]| -> Vec<Token> {
            ps.iter()
                .filter_map(|p| match p {
                    Part::Token(t) => Some(t.clone()),
                    Part::Block { .. } => None,
                })
                .collect()
        };
        let block_at = parts.iter().position(|p| matches!(p, Part::Block { .. }));
        let Some(b) = block_at else {
            self.tokens_with_comments(&tokens(parts), 0);
            return;
        };
        let (head, tail) = (tokens(&parts[..b]), tokens(&parts[b + 1..]));
        let Part::Block {
            fields,
            open,
            close,
        } = &parts[b]
        else {
            return;
        };
        let head_text = join(&head);
        let tail_text = join(&tail);
        let field_texts: Vec<String> = fields.iter().map(|f| join(&f.tokens)).collect();
        let one_line = if field_texts.is_empty() {
            format!("{head_text} {{}}")
        } else {
            format!("{head_text} {{ {} }}", field_texts.join(", "))
        };
        let one_line = if tail_text.is_empty() {
            one_line
        } else {
            format!("{one_line} {tail_text}")
        };
        let brace = |at: usize, text: &str| Token {
            kind: if text == "{" { Kind::Open } else { Kind::Close },
            text: text.to_string(),
            start: at,
            end: at + 1,
        };
        let mut head = head;
        head.push(brace(*open, "{"));
        let mut tail = tail;
        tail.insert(0, brace(close - 1, "}"));
        let spans: Vec<(usize, usize)> = head
            .iter()
            .chain(fields.iter().flat_map(|f| &f.tokens))
            .chain(&tail)
            .map(|t| (t.start, t.end))
            .collect();
        // The author's choice: a block written over several lines stays one
        // field per line.
        let written_multiline = !fields.is_empty() && self.src[*open..*close].contains('\n');
        if !self.commented(&spans) && !written_multiline && one_line.len() <= WIDTH {
            self.line(0, &one_line);
            return;
        }
        // Comments inside the head or the tail move to the end of the item's
        // first or last line.
        self.line(0, &format!("{head_text} {{"));
        self.inner_comments(&head);
        let mut pos = *open + 1;
        for (f, text) in fields.iter().zip(&field_texts) {
            let (Some(first), Some(last)) = (f.tokens.first(), f.tokens.last()) else {
                continue;
            };
            self.gap(pos, first.start, 2);
            self.line(2, text);
            self.inner_comments(&f.tokens);
            pos = last.end;
        }
        self.gap(pos, close - 1, 2);
        let closing = if tail_text.is_empty() {
            "}".to_string()
        } else {
            format!("}} {tail_text}")
        };
        self.blank = false;
        self.line(0, &closing);
        self.inner_comments(&tail);
    }

    /// Tokens on one line, the comments between them after it.
    fn tokens_with_comments(&mut self, tokens: &[Token], indent: usize) {
        self.line(indent, &join(tokens));
        self.inner_comments(tokens);
    }

    /// Comments between tokens (inside an expression, a head or a field): at
    /// the end of the line just written, then on lines of their own.
    fn inner_comments(&mut self, tokens: &[Token]) {
        let mut first = true;
        for w in tokens.windows(2) {
            let gap = &self.src[w[0].end..w[1].start];
            let mut rest = gap;
            while let Some(hash) = rest.find('#') {
                let end = rest[hash..].find('\n').map_or(rest.len(), |e| hash + e);
                let comment = rest[hash..end].trim_end().to_string();
                if first {
                    let at = w[1].start - rest.len() + hash;
                    self.trailing(&comment, at);
                    first = false;
                } else {
                    self.line(2, &comment);
                }
                rest = &rest[end..];
            }
        }
    }

    /// The text, with the comments after code aligned over each run of
    /// consecutive lines that have one (two spaces after the longest code).
    fn finish(mut self) -> String {
        while self.text.ends_with("\n\n") {
            self.text.pop();
        }
        let mut lines: Vec<String> = self.text.lines().map(str::to_string).collect();
        let mut i = 0;
        while i < self.trailing.len() {
            let mut j = i + 1;
            while j < self.trailing.len() && self.trailing[j].0 == self.trailing[j - 1].0 + 1 {
                j += 1;
            }
            let longest = self.trailing[i..j].iter().map(|t| t.1).max().unwrap_or(0);
            // A run aligned in the source at a column wide enough keeps it.
            let column = self.trailing[i].2;
            let aligned = self.trailing[i..j].iter().all(|t| t.2 == column);
            let width = if aligned && column >= longest + 2 {
                column - 2
            } else {
                longest
            };
            for &(line, code, _) in &self.trailing[i..j] {
                if let Some(l) = lines.get_mut(line) {
                    // The two spaces after the code become enough to align.
                    l.insert_str(code, &" ".repeat(width - code));
                }
            }
            i = j;
        }
        let mut out = lines.join("\n");
        out.push('\n');
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(s: &str) -> String {
        format(s).unwrap_or_else(|d| panic!("{d:?}"))
    }

    #[test]
    fn spacing_is_canonical_and_the_tokens_stay() {
        let src = "let  w=2 *(x-1)^2+ -3 kN / m\nlet h = sqrt( w )/2\n";
        // `*` and `/` stay spaced or not, as written (`2*x`).
        assert_eq!(
            fmt(src),
            "let w = 2 * (x - 1)^2 + -3 kN/m\nlet h = sqrt(w)/2\n"
        );
    }

    #[test]
    fn short_blocks_go_on_one_line_and_long_ones_one_field_per_line() {
        let src = "material steel {E = 210 GPa,nu=0.3}\n";
        assert_eq!(fmt(src), "material steel { E = 210 GPa, nu = 0.3 }\n");
        // Written over several lines: the author's choice stays.
        let src = "material steel {\n  E = 210 GPa,nu = 0.3\n}\n";
        assert_eq!(fmt(src), "material steel {\n  E = 210 GPa\n  nu = 0.3\n}\n");
        let long = format!(
            "body b {{ material = steel, x = 0 .. 1, y = 0 .. 1, bottom = {}, mesh = 4 x 4 }}\n",
            "0.1 + 0.2 * x".repeat(8).replace("x0.1", "x + 0.1")
        );
        let out = fmt(&long);
        assert!(
            out.starts_with("body b {\n  material = steel\n  x = 0 .. 1\n"),
            "{out}"
        );
        assert!(out.ends_with("  mesh = 4 x 4\n}\n"), "{out}");
        assert_eq!(fmt(&out), out, "idempotent");
    }

    #[test]
    fn comments_stay_where_they_were() {
        let src = "# head\n\nlet a = 1 # one\n# about b\nlet b = 2\nmaterial m {\n  E = 1  # stiff\n  # soft\n  nu = 0.3,\n}\n";
        let out = fmt(src);
        assert_eq!(
            out,
            "# head\n\nlet a = 1  # one\n# about b\nlet b = 2\nmaterial m {\n  E = 1  # stiff\n  # soft\n  nu = 0.3\n}\n"
        );
        assert_eq!(fmt(&out), out);
    }

    #[test]
    fn comments_after_code_align_over_consecutive_lines() {
        // Aligned in the source far enough: the column stays.
        let aligned = "let R = 50 mm       # radius\nlet P = 2 MN/m      # load\n";
        assert_eq!(fmt(aligned), aligned);
        let src = "let R = 50 mm    # radius\nlet Pmax = 80 kN # force\n\nlet a = 1 # alone\n";
        assert_eq!(
            fmt(src),
            "let R = 50 mm     # radius\nlet Pmax = 80 kN  # force\n\nlet a = 1  # alone\n"
        );
    }

    #[test]
    fn selections_calls_indices_lists_and_unary_operators() {
        let src = "fix base.bottom[ x>=1&&x<= 2 ]{ux}\ndesign a [3] {init=[0 ,1,2], lower = -1, upper = 3}\ntraction p.top=(0,-5)\nsubject to area( p )<=initial( area(p) )\n";
        assert_eq!(
            fmt(src),
            "fix base.bottom[x >= 1 && x <= 2] { ux }\ndesign a[3] { init = [0, 1, 2], lower = -1, upper = 3 }\ntraction p.top = (0, -5)\nsubject to area(p) <= initial(area(p))\n"
        );
    }

    #[test]
    fn a_file_with_syntax_errors_is_not_formatted() {
        assert!(format("let a = (1\n").is_err());
    }
}
