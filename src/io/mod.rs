//! What cso shows a person: summaries and (later) reports, VTU and SVG.

pub mod summary;
