//! The `.cso` front end: text -> syntax tree -> checked [`Scene`].
//!
//! [`parse`] turns text into a spanned [`ast`]; [`check`] resolves names, fields,
//! dimensions and units into a [`scene::Scene`] in SI units, collecting every error
//! as a [`diag::Diagnostic`]. Geometry stays symbolic ([`expr::Formula`]) so that
//! exact derivatives with respect to design variables come from the same code.

pub mod ast;
pub mod check;
pub mod diag;
pub mod expr;
pub mod fmt;
pub mod functional;
pub mod ide;
pub mod parse;
pub mod scene;
pub mod suggest;
pub mod units;

pub use check::{analyze, compile, CheckOptions};
pub use diag::Diagnostic;
pub use scene::Scene;
