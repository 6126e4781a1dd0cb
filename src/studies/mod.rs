//! Studies: the solver run many times over a family of scenes or settings, to
//! measure it rather than to answer one question about one scene.
//!
//! A state solve or a gradient gives one result; a study sweeps what it depends
//! on (decomposition, method, step, tolerance, pivot tolerance, material contrast)
//! and returns plain data (rows, sweeps, tables, charts) that `cso compare`,
//! `cso bench` and `cso sensitivity --study` print and write. Nothing here changes
//! how a scene is solved: every run goes through the same state and sensitivity
//! code as `cso solve`.

pub mod bench;
pub mod bench_tables;
pub mod compare;
pub mod convergence;
pub mod hertz;
pub mod measure;
pub mod output;
pub mod refine;
pub mod sensitivity;
pub mod stability;
pub mod tolerance;
pub mod traffic;

/// Free text (an error message, a formula with `|u|`) as one Markdown table
/// cell: a bare `|` would end the cell and shift every column after it.
pub fn md_cell(text: &str) -> String {
    text.replace('|', "\\|").replace('\n', " ")
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_bar_in_a_cell_does_not_split_it() {
        let row = format!("| {} | x |", super::md_cell("max |u| / 2"));
        // Unescaped bars are exactly the three column separators.
        let bars = row
            .match_indices('|')
            .filter(|(i, _)| !row[..*i].ends_with('\\'));
        assert_eq!(bars.count(), 3, "{row}");
    }
}
