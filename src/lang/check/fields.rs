//! Fields of a block: which are known, which are required, and their values' shapes.

use super::{quote_list, Checker};
use crate::lang::ast::{Block, Expr, Field, Span, Value};
use crate::lang::diag::Diagnostic;

/// One field a block accepts.
pub(crate) struct Spec {
    pub name: &'static str,
    pub required: bool,
    /// What to write, for the hint when it is missing: `E = 210 GPa`.
    pub example: &'static str,
}

pub(crate) const fn req(name: &'static str, example: &'static str) -> Spec {
    Spec {
        name,
        required: true,
        example,
    }
}

pub(crate) const fn opt(name: &'static str, example: &'static str) -> Spec {
    Spec {
        name,
        required: false,
        example,
    }
}

/// The fields of one block, by name, after checking names.
pub(crate) struct Fields<'a> {
    found: Vec<&'a Field>,
}

impl<'a> Fields<'a> {
    pub fn get(&self, name: &str) -> Option<&'a Field> {
        self.found.iter().copied().find(|f| f.name.name == name)
    }
}

impl<'a> Checker<'a> {
    /// Checks a block's field names against `spec`: unknown (with a suggestion),
    /// given twice, required and missing. `what` names the block in messages
    /// ("material `steel`"), `at` is where to point when a field is missing.
    /// `unknown_hint` overrides the hint for a field not in `spec`.
    pub(crate) fn fields(
        &mut self,
        block: &'a Block,
        spec: &[Spec],
        what: &str,
        at: Span,
        unknown_hint: &dyn Fn(&str) -> Option<String>,
    ) -> Fields<'a> {
        let mut found: Vec<&'a Field> = Vec::new();
        // Fields written without a value: reported here, but still "given".
        let mut valueless: Vec<&str> = Vec::new();
        let mut skip_next = false;
        for (i, field) in block.fields.iter().enumerate() {
            if std::mem::take(&mut skip_next) {
                continue;
            }
            let name = field.name.name.as_str();
            if field.value.is_none() {
                valueless.push(name);
                let next = block.fields.get(i + 1).filter(|n| {
                    n.value.is_none()
                        && self
                            .src
                            .get(field.span.end..n.span.start)
                            .is_some_and(|gap| gap.chars().all(|c| c == ' ' || c == '\t'))
                });
                let after_grid = i
                    .checked_sub(1)
                    .and_then(|j| block.fields.get(j))
                    .filter(|p| {
                        matches!(p.value, Some(Value::Grid(_) | Value::Expr(_))) && name == "x"
                    })
                    .filter(|p| {
                        self.src
                            .get(p.span.end..field.span.start)
                            .is_some_and(|gap| gap.chars().all(|c| c == ' ' || c == '\t'))
                    });
                if after_grid.is_none() && self.unit_after_name(block, i) {
                    continue;
                }
                if let Some(p) = after_grid {
                    // `mesh = 4 x`: the counts are incomplete; report that once.
                    found.retain(|f| f.name.name != p.name.name);
                    valueless.push(p.name.name.as_str());
                }
                let d = match (after_grid, next) {
                    (Some(p), _) => Diagnostic::new("cso::syntax", "expected a count after `x`")
                        .label(field.name.span, "expected a count after this `x`")
                        .help(format!(
                            "complete the counts (`{0} = 4 x 4` in 2D, `{0} = 4 x 4 x 4` in 3D) or drop the last `x`",
                            p.name.name
                        )),
                    (None, Some(n)) => {
                        skip_next = true;
                        Diagnostic::new(
                            "cso::syntax",
                            format!("expected `=` between `{name}` and `{}`", n.name.name),
                        )
                        .label(field.span.to(n.span), "missing `=`")
                        .help(format!("write `{name} = {}`", n.name.name))
                    }
                    (None, None) => Diagnostic::new("cso::missing-value", format!("field `{name}` has no value"))
                        .label(field.name.span, format!("expected `{name} = ...`"))
                        .help("every field of this block is written `NAME = VALUE`"),
                };
                self.error(d);
                continue;
            }
            if !spec.iter().any(|s| s.name == name) {
                let known: Vec<&str> = spec.iter().map(|s| s.name).collect();
                let help = unknown_hint(name)
                    .or_else(|| crate::lang::suggest::did_you_mean(name, known.iter().copied()))
                    .unwrap_or_else(|| format!("the fields of {what} are {}", quote_list(&known)));
                // A misspelt required field is not also reported as missing: the
                // hint names the field it was meant to be.
                for s in spec {
                    if help.contains(&format!("`{}`", s.name)) && !help.starts_with("the fields of")
                    {
                        valueless.push(s.name);
                    }
                }
                self.error(
                    Diagnostic::new(
                        "cso::unknown-field",
                        format!("unknown field `{name}` in {what}"),
                    )
                    .label(field.name.span, "not a field here")
                    .help(help),
                );
                continue;
            }
            if let Some(first) = found.iter().find(|f| f.name.name == name) {
                self.error(
                    Diagnostic::new(
                        "cso::duplicate",
                        format!("field `{name}` is given twice in {what}"),
                    )
                    .label(field.name.span, "given again here")
                    .label(first.name.span, "first given here")
                    .help("keep one of them"),
                );
                continue;
            }
            found.push(field);
        }
        self.missing_fields(spec, &found, &valueless, what, at);
        Fields { found }
    }

    /// Reports the required fields of `spec` neither found nor written without a
    /// value.
    fn missing_fields(
        &mut self,
        spec: &[Spec],
        found: &[&Field],
        valueless: &[&str],
        what: &str,
        at: Span,
    ) {
        let missing: Vec<&Spec> = spec
            .iter()
            .filter(|s| {
                s.required
                    && !found.iter().any(|f| f.name.name == s.name)
                    && !valueless.contains(&s.name)
            })
            .collect();
        if !missing.is_empty() {
            let names: Vec<&str> = missing.iter().map(|s| s.name).collect();
            let examples: Vec<String> =
                missing.iter().map(|s| format!("`{}`", s.example)).collect();
            let noun = if missing.len() == 1 {
                "field"
            } else {
                "fields"
            };
            self.error(
                Diagnostic::new(
                    "cso::missing-field",
                    format!("{what} lacks the required {noun} {}", quote_list(&names)),
                )
                .label(at, format!("{} missing", quote_list(&names)))
                .help(format!("add {}", examples.join(", "))),
            );
        }
    }

    /// The expression of a field, or an error if it has none or is a range or grid.
    pub(crate) fn expr_of(&mut self, field: &'a Field, expect: &str) -> Option<&'a Expr> {
        match &field.value {
            Some(Value::Expr(e)) => Some(e),
            Some(other) => {
                let found = match other {
                    Value::Range(..) => "a range `a .. b`",
                    _ => "a grid `n x m`",
                };
                self.error(
                    Diagnostic::new(
                        "cso::wrong-value",
                        format!("`{}` expects {expect}, found {found}", field.name.name),
                    )
                    .label(other.span(), format!("expected {expect}")),
                );
                None
            }
            None => {
                self.error(self.needs_value(field, expect));
                None
            }
        }
    }

    /// The two ends of a range field `a .. b`.
    pub(crate) fn range_of(&mut self, field: &'a Field) -> Option<(&'a Expr, &'a Expr)> {
        match &field.value {
            Some(Value::Range(a, b)) => Some((a, b)),
            Some(other) => {
                let n = &field.name.name;
                self.error(
                    Diagnostic::new(
                        "cso::wrong-value",
                        format!("`{n}` expects a range `from .. to`"),
                    )
                    .label(other.span(), "expected a range")
                    .help(format!("write e.g. `{n} = 0 .. 1`")),
                );
                None
            }
            None => {
                self.error(self.needs_value(field, "a range `from .. to`"));
                None
            }
        }
    }

    /// The entries of a grid field `16 x 16` (a lone number counts as one entry).
    pub(crate) fn grid_of(&mut self, field: &'a Field) -> Option<Vec<&'a Expr>> {
        match &field.value {
            Some(Value::Grid(g)) => Some(g.iter().collect()),
            Some(Value::Expr(e)) => Some(vec![e]),
            Some(other) => {
                let n = &field.name.name;
                self.error(
                    Diagnostic::new(
                        "cso::wrong-value",
                        format!("`{n}` expects counts along each axis, like `16 x 16`"),
                    )
                    .label(other.span(), "expected `n x m`"),
                );
                None
            }
            None => {
                self.error(self.needs_value(field, "counts like `16 x 16`"));
                None
            }
        }
    }

    /// `x = 0 .. w mm`: a unit written after a name on the same line (a
    /// number takes its unit directly, `10 mm`) parses as a field of its own
    /// without a value; say what it is. True where it reported that.
    fn unit_after_name(&mut self, block: &Block, i: usize) -> bool {
        let Some(field) = block.fields.get(i) else {
            return false;
        };
        let name = field.name.name.as_str();
        let unit_after = i
            .checked_sub(1)
            .and_then(|j| block.fields.get(j))
            .filter(|p| p.value.is_some() && crate::lang::units::is_unit(name))
            .filter(|p| {
                self.src
                    .get(p.span.end..field.span.start)
                    .is_some_and(|gap| gap.chars().all(|c| c == ' ' || c == '\t'))
            });
        let Some(p) = unit_after else {
            return false;
        };
        let text = self.src.get(p.span.start..p.span.end).unwrap_or_default();
        let value = text.split_once('=').map_or(text, |(_, v)| v).trim();
        let last = value
            .rsplit(|c: char| !(c.is_alphanumeric() || c == '_'))
            .next()
            .filter(|n| !n.is_empty())
            .unwrap_or("NAME");
        self.error(
            Diagnostic::new(
                "cso::unit",
                format!("a unit cannot follow a name: `{name}` after `{value}`"),
            )
            .label(field.name.span, "a unit after a name")
            .help(format!(
                "a constant carries its unit where it is defined: write it in the `let` \
                 (`let {last} = 10 {name}`) and use the name alone; or multiply: \
                 `{last} * 1 {name}`"
            )),
        );
        true
    }

    fn needs_value(&self, field: &Field, expect: &str) -> Diagnostic {
        let n = &field.name.name;
        Diagnostic::new("cso::missing-value", format!("field `{n}` has no value"))
            .label(field.name.span, format!("expected `{n} = ...`"))
            .help(format!("`{n}` expects {expect}"))
    }
}
