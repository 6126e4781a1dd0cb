//! The `.cso` front end: text -> syntax tree -> checked [`Scene`].

pub mod ast;
pub mod diag;
pub mod parse;
