//! What cso shows a person: summaries and (later) reports, VTU and SVG.

pub mod atomic;
pub mod export;
pub mod plot;
pub mod report;
pub mod summary;
pub mod vtu;
