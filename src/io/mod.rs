//! What cso shows a person: summaries, reports, tables, VTU and SVG, and the
//! files each command writes.

pub mod atomic;
pub mod contact_charts;
pub mod deformed;
pub mod export;
pub mod msh;
pub mod optimization;
pub mod outputs;
pub mod plot;
pub mod png;
pub mod pressure;
pub mod provenance;
pub mod report;
pub mod solve_files;
pub mod summary;
pub mod tables;
pub mod vtu;
