//! Name tables and "did you mean" suggestions.

use crate::lang::ast::Span;
use std::collections::HashMap;

/// The kinds of named things; names are unique per kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    Let,
    Design,
    Material,
    Body,
    Obstacle,
    Glue,
    Contact,
    Probe,
}

impl Kind {
    pub fn noun(self) -> &'static str {
        match self {
            Kind::Let => "constant",
            Kind::Design => "design variable",
            Kind::Material => "material",
            Kind::Body => "body",
            Kind::Obstacle => "obstacle",
            Kind::Glue => "glue",
            Kind::Contact => "contact",
            Kind::Probe => "probe",
        }
    }

    /// "bodies", "materials".
    pub fn plural(self) -> String {
        match self {
            Kind::Body => "bodies".to_string(),
            Kind::Design => "design variables".to_string(),
            k => format!("{}s", k.noun()),
        }
    }

    /// "a body", "an obstacle".
    pub fn article(self) -> String {
        let n = self.noun();
        if n.starts_with(['a', 'e', 'i', 'o', 'u']) {
            format!("an {n}")
        } else {
            format!("a {n}")
        }
    }

    pub const ALL: [Kind; 8] = [
        Kind::Let,
        Kind::Design,
        Kind::Material,
        Kind::Body,
        Kind::Obstacle,
        Kind::Glue,
        Kind::Contact,
        Kind::Probe,
    ];
}

/// Names of one kind, in order of definition.
#[derive(Debug, Default)]
pub struct Table {
    pub names: Vec<String>,
    pub spans: Vec<Span>,
    index: HashMap<String, usize>,
}

impl Table {
    /// Adds a name; returns the span of an earlier definition if there is one.
    pub fn insert(&mut self, name: &str, span: Span) -> Result<usize, Span> {
        if let Some(&i) = self.index.get(name) {
            return Err(self.spans[i]);
        }
        let i = self.names.len();
        self.names.push(name.to_string());
        self.spans.push(span);
        self.index.insert(name.to_string(), i);
        Ok(i)
    }

    pub fn get(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

/// Edit distance counting a swap of two neighbours as one edit (optimal string
/// alignment), so `sfot` is one typo away from `soft`. Small strings only.
pub fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let (n, m) = (a.len(), b.len());
    let mut d = vec![vec![0usize; m + 1]; n + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=n {
        for j in 1..=m {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = v;
        }
    }
    d[n][m]
}

/// The closest candidate, if it is close enough to be a plausible typo.
pub fn suggest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (name.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .map(|c| {
            let d = if c.eq_ignore_ascii_case(name) {
                0
            } else {
                distance(name, c)
            };
            (d, c)
        })
        .filter(|(d, c)| *d <= limit && *c != name)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// "; did you mean `x`?" or nothing.
pub fn did_you_mean<'a>(
    name: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<String> {
    suggest(name, candidates).map(|s| format!("did you mean `{s}`?"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions_catch_typos_and_ignore_strangers() {
        assert_eq!(distance("punh", "punch"), 1);
        assert_eq!(suggest("punh", ["base", "punch"]), Some("punch"));
        assert_eq!(suggest("E", ["E", "nu"]), None);
        assert_eq!(suggest("e", ["E", "nu"]), Some("E"));
        assert_eq!(suggest("zzz", ["base", "punch"]), None);
        assert_eq!(distance("sfot", "soft"), 1);
        assert_eq!(suggest("sfot", ["steel", "soft"]), Some("soft"));
    }
}
