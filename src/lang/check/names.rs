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
