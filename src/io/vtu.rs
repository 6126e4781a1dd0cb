//! VTK XML unstructured grids (`.vtu`) and ParaView collections (`.pvd`).
//!
//! Meshes, displacements, stresses, contact pressures and the active set of each
//! iteration are looked at in ParaView, so they are written in the format it
//! reads natively. The format is short enough to write by hand (`vtkio` writes
//! wrong attributes for unstructured pieces), and ASCII keeps the files
//! diffable and checkable by eye; the cost is size, which matters little at the
//! mesh sizes one inspects visually.
//!
//! # Wire format
//! ```xml
//! <VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
//!   <UnstructuredGrid><Piece NumberOfPoints=".." NumberOfCells="..">
//!     <PointData> DataArray per field </PointData>
//!     <CellData> DataArray per field </CellData>
//!     <Points> Float64 x 3 </Points>
//!     <Cells> Int64 connectivity, Int64 offsets, UInt8 types </Cells>
//!   </Piece></UnstructuredGrid>
//! </VTKFile>
//! ```
//! Floats are written so that they read back to the same `f64` (Rust's
//! shortest round-trip formatting). Non-finite floats are written as `0`: the
//! caller guarantees finite values, and this last guard exists because a
//! single `nan` token makes some readers reject the whole file, which would hide
//! every other field of that iteration. Names are XML-escaped.

use std::fmt::Write;

/// The VTK cell type shared by all cells of a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellType {
    /// Bilinear quadrilateral (`VTK_QUAD` = 9), nodes counter-clockwise.
    Quad,
    /// Trilinear hexahedron (`VTK_HEXAHEDRON` = 12), bottom face
    /// counter-clockwise then top face in the same order.
    Hexahedron,
}

impl CellType {
    /// The cell type number in VTK's `types` array.
    pub fn vtk_id(self) -> u8 {
        match self {
            CellType::Quad => 9,
            CellType::Hexahedron => 12,
        }
    }

    /// Nodes per cell.
    pub fn nodes(self) -> usize {
        match self {
            CellType::Quad => 4,
            CellType::Hexahedron => 8,
        }
    }
}

/// A mesh to write. 2D meshes pass `z = 0`: VTK points always have three
/// coordinates.
#[derive(Debug, Clone, Copy)]
pub struct VtuMesh<'a> {
    pub points: &'a [[f64; 3]],
    /// Point indices of each cell, `cell_type.nodes()` of them, in VTK order.
    pub cells: &'a [Vec<usize>],
    pub cell_type: CellType,
}

/// Values attached to every point or every cell.
#[derive(Debug, Clone, Copy)]
pub enum Field<'a> {
    /// One float per entity (von Mises stress, gap, contact pressure).
    Scalar(&'a [f64]),
    /// Three floats per entity (displacement; 2D callers pass z = 0 so that
    /// ParaView's "Warp By Vector" works unchanged).
    Vector(&'a [[f64; 3]]),
    /// One integer per entity (subdomain id, active-set flag, body id).
    Int(&'a [i64]),
}

impl Field<'_> {
    fn len(&self) -> usize {
        match self {
            Field::Scalar(v) => v.len(),
            Field::Vector(v) => v.len(),
            Field::Int(v) => v.len(),
        }
    }
}

/// The `.vtu` file for one mesh and its fields.
///
/// The caller guarantees that each point field has one entry per point, each
/// cell field one per cell, and each cell `cell_type.nodes()` valid point
/// indices: these are facts about the caller's own arrays, not user input.
/// A field of the wrong length is a bug that debug builds stop on; release
/// builds leave that field out rather than write a file ParaView rejects.
pub fn vtu_string(
    mesh: &VtuMesh,
    point_data: &[(&str, Field)],
    cell_data: &[(&str, Field)],
) -> String {
    let n_points = mesh.points.len();
    let n_cells = mesh.cells.len();
    debug_assert!(
        mesh.cells
            .iter()
            .all(|c| c.len() == mesh.cell_type.nodes() && c.iter().all(|&i| i < n_points)),
        "cells must have {} valid point indices each",
        mesh.cell_type.nodes()
    );

    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str("<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n");
    s.push_str("  <UnstructuredGrid>\n");
    // `write!` into a String cannot fail; the results are ignored for that reason.
    let _ = writeln!(
        s,
        "    <Piece NumberOfPoints=\"{n_points}\" NumberOfCells=\"{n_cells}\">"
    );

    write_fields(&mut s, "PointData", point_data, n_points);
    write_fields(&mut s, "CellData", cell_data, n_cells);

    s.push_str("      <Points>\n");
    s.push_str(
        "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"ascii\">\n",
    );
    for p in mesh.points {
        push_floats(&mut s, p);
    }
    s.push_str("        </DataArray>\n");
    s.push_str("      </Points>\n");

    s.push_str("      <Cells>\n");
    s.push_str("        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for cell in mesh.cells {
        push_ints(&mut s, cell.iter().map(|&i| i as i64));
    }
    s.push_str("        </DataArray>\n");
    s.push_str("        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    // Offsets are the running end of each cell's connectivity, so they follow
    // the actual cell lengths even if a caller mixed lengths by mistake.
    let mut end = 0i64;
    for chunk in mesh.cells.chunks(16) {
        push_ints(
            &mut s,
            chunk.iter().map(|c| {
                end += c.len() as i64;
                end
            }),
        );
    }
    s.push_str("        </DataArray>\n");
    s.push_str("        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    let id = i64::from(mesh.cell_type.vtk_id());
    for chunk in mesh.cells.chunks(16) {
        push_ints(&mut s, chunk.iter().map(|_| id));
    }
    s.push_str("        </DataArray>\n");
    s.push_str("      </Cells>\n");

    s.push_str("    </Piece>\n");
    s.push_str("  </UnstructuredGrid>\n");
    s.push_str("</VTKFile>\n");
    s
}

/// A ParaView collection listing one `.vtu` per time step or iteration, so the
/// whole history opens as one animated data set. `file` paths are written as
/// given (relative paths resolve against the `.pvd`'s directory). A non-finite
/// time is written as `0`, as in [`vtu_string`].
pub fn pvd_string(entries: &[(f64, &str)]) -> String {
    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str("<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n");
    s.push_str("  <Collection>\n");
    for &(time, file) in entries {
        let _ = writeln!(
            s,
            "    <DataSet timestep=\"{}\" group=\"\" part=\"0\" file=\"{}\"/>",
            fmt_float(time),
            xml_escape(file)
        );
    }
    s.push_str("  </Collection>\n");
    s.push_str("</VTKFile>\n");
    s
}

/// One `<PointData>` or `<CellData>` block; fields whose length is not `n`
/// are left out (see [`vtu_string`]).
fn write_fields(s: &mut String, tag: &str, fields: &[(&str, Field)], n: usize) {
    let _ = writeln!(s, "      <{tag}>");
    for (name, field) in fields {
        debug_assert_eq!(field.len(), n, "{tag} field {name:?} has the wrong length");
        if field.len() != n {
            continue;
        }
        // One-component arrays carry no NumberOfComponents: VTK defaults it to
        // 1, and meshio then reads a flat array instead of an n x 1 matrix.
        let (ty, comps) = match field {
            Field::Scalar(_) => ("Float64", ""),
            Field::Vector(_) => ("Float64", " NumberOfComponents=\"3\""),
            Field::Int(_) => ("Int64", ""),
        };
        let _ = writeln!(
            s,
            "        <DataArray type=\"{ty}\" Name=\"{}\"{comps} format=\"ascii\">",
            xml_escape(name)
        );
        match field {
            Field::Scalar(v) => {
                for chunk in v.chunks(8) {
                    push_floats(s, chunk);
                }
            }
            Field::Vector(v) => {
                for x in *v {
                    push_floats(s, x);
                }
            }
            Field::Int(v) => {
                for chunk in v.chunks(16) {
                    push_ints(s, chunk.iter().copied());
                }
            }
        }
        s.push_str("        </DataArray>\n");
    }
    let _ = writeln!(s, "      </{tag}>");
}

/// One indented line of floats.
fn push_floats(s: &mut String, values: &[f64]) {
    s.push_str("         ");
    for &v in values {
        s.push(' ');
        s.push_str(&fmt_float(v));
    }
    s.push('\n');
}

/// One indented line of integers.
fn push_ints(s: &mut String, values: impl Iterator<Item = i64>) {
    s.push_str("         ");
    for v in values {
        let _ = write!(s, " {v}");
    }
    s.push('\n');
}

/// Shortest text that reads back to the same `f64`; plain notation where it is
/// short (Rust's `{}` never uses an exponent, so 1e300 would be 301 digits),
/// exponent notation elsewhere. Non-finite values become `0` (module docs).
fn fmt_float(v: f64) -> String {
    if !v.is_finite() {
        return "0".to_string();
    }
    let a = v.abs();
    if a == 0.0 || (1e-5..1e15).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Escapes the five XML special characters so any field or file name is a valid
/// attribute value.
fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            _ => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::process::Command;

    /// Two unit quads side by side: points 0..6 on a 3 x 2 grid.
    fn two_quads() -> (Vec<[f64; 3]>, Vec<Vec<usize>>) {
        let points = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [2.0, 1.0, 0.0],
        ];
        let cells = vec![vec![0, 1, 4, 3], vec![1, 2, 5, 4]];
        (points, cells)
    }

    /// The whitespace-separated tokens of the first `DataArray` named `name`.
    fn array_tokens<'s>(xml: &'s str, name: &str) -> Vec<&'s str> {
        let start = xml
            .find(&format!("Name=\"{name}\""))
            .unwrap_or_else(|| panic!("no array {name}"));
        let body_start = start + xml[start..].find('>').unwrap() + 1;
        let body_end = body_start + xml[body_start..].find("</DataArray>").unwrap();
        xml[body_start..body_end].split_whitespace().collect()
    }

    #[test]
    fn two_quads_structure() {
        let (points, cells) = two_quads();
        let mesh = VtuMesh {
            points: &points,
            cells: &cells,
            cell_type: CellType::Quad,
        };
        let ux: Vec<[f64; 3]> = points.iter().map(|p| [0.1 * p[0], 0.0, 0.0]).collect();
        let xml = vtu_string(
            &mesh,
            &[("u", Field::Vector(&ux))],
            &[
                ("subdomain", Field::Int(&[0, 1])),
                ("vm", Field::Scalar(&[1.5, 2.5])),
            ],
        );
        assert!(xml.starts_with("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\""));
        assert!(xml.contains("version=\"0.1\" byte_order=\"LittleEndian\""));
        assert!(xml.contains("<Piece NumberOfPoints=\"6\" NumberOfCells=\"2\">"));
        assert_eq!(
            array_tokens(&xml, "connectivity"),
            ["0", "1", "4", "3", "1", "2", "5", "4"]
        );
        assert_eq!(array_tokens(&xml, "offsets"), ["4", "8"]);
        assert_eq!(array_tokens(&xml, "types"), ["9", "9"]);
        assert_eq!(array_tokens(&xml, "Points").len(), 18);
        assert_eq!(array_tokens(&xml, "subdomain"), ["0", "1"]);
        assert_eq!(array_tokens(&xml, "vm"), ["1.5", "2.5"]);
        assert_eq!(array_tokens(&xml, "u")[3], "0.1");
        assert_eq!(xml.matches("<DataArray").count(), 7);
        assert_eq!(xml.matches("</DataArray>").count(), 7);
        assert!(xml.ends_with("</VTKFile>\n"));
    }

    #[test]
    fn floats_round_trip_and_non_finite_become_zero() {
        for v in [0.1, -2.5e-300, 1e300, 1.0 / 3.0, 123456.789, -0.0, 5e-6] {
            assert_eq!(fmt_float(v).parse::<f64>().unwrap(), v, "{v}");
        }
        assert_eq!(fmt_float(f64::NAN), "0");
        assert_eq!(fmt_float(f64::INFINITY), "0");
        assert_eq!(fmt_float(f64::NEG_INFINITY), "0");
        let (points, cells) = two_quads();
        let mesh = VtuMesh {
            points: &points,
            cells: &cells,
            cell_type: CellType::Quad,
        };
        let xml = vtu_string(&mesh, &[], &[("p", Field::Scalar(&[f64::NAN, 1e300]))]);
        assert_eq!(array_tokens(&xml, "p"), ["0", "1e300"]);
        assert!(!xml.to_lowercase().contains("nan"));
        assert!(!xml.contains("inf"));
    }

    #[test]
    fn names_are_escaped() {
        let (points, cells) = two_quads();
        let mesh = VtuMesh {
            points: &points,
            cells: &cells,
            cell_type: CellType::Quad,
        };
        let xml = vtu_string(&mesh, &[], &[("a<b> & \"c\"", Field::Int(&[1, 2]))]);
        assert!(xml.contains("Name=\"a&lt;b&gt; &amp; &quot;c&quot;\""));
        let pvd = pvd_string(&[(0.0, "it&0.vtu")]);
        assert!(pvd.contains("file=\"it&amp;0.vtu\""));
    }

    #[test]
    fn pvd_lists_every_step() {
        let pvd = pvd_string(&[
            (0.0, "out_000.vtu"),
            (1.0, "out_001.vtu"),
            (f64::NAN, "x.vtu"),
        ]);
        assert!(pvd.starts_with("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\""));
        assert_eq!(pvd.matches("<DataSet ").count(), 3);
        assert!(
            pvd.contains("<DataSet timestep=\"1\" group=\"\" part=\"0\" file=\"out_001.vtu\"/>")
        );
        assert!(pvd.contains("timestep=\"0\" group=\"\" part=\"0\" file=\"x.vtu\""));
        assert_eq!(pvd.matches("<Collection>").count(), 1);
        assert_eq!(pvd.matches("</Collection>").count(), 1);
        assert!(pvd.trim_end().ends_with("</VTKFile>"));
        let empty = pvd_string(&[]);
        assert!(empty.contains("<Collection>\n  </Collection>"));
    }

    /// Runs `script` (Python, with the file path in `sys.argv[1]`) on `xml`
    /// written to a temporary file; `None` when Python or meshio is missing, so
    /// machines without them skip the check instead of failing.
    fn run_meshio(test: &str, xml: &str, script: &str) -> Option<String> {
        let has_meshio = Command::new("python3")
            .args(["-c", "import meshio"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false);
        if !has_meshio {
            eprintln!("skipping {test}: python3 with meshio is not available (pip install meshio)");
            return None;
        }
        let path: PathBuf =
            std::env::temp_dir().join(format!("cso-vtu-{}-{test}.vtu", std::process::id()));
        crate::io::atomic::write_atomic(&path, xml.as_bytes()).unwrap();
        let out = Command::new("python3")
            .args(["-c", script])
            .arg(&path)
            .output()
            .unwrap();
        let _ = std::fs::remove_file(&path);
        assert!(
            out.status.success(),
            "meshio failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        Some(String::from_utf8_lossy(&out.stdout).trim().to_string())
    }

    #[test]
    fn meshio_reads_quads() {
        let (points, cells) = two_quads();
        let mesh = VtuMesh {
            points: &points,
            cells: &cells,
            cell_type: CellType::Quad,
        };
        let u: Vec<[f64; 3]> = points
            .iter()
            .map(|p| [0.1 * p[0], -1.0 / 3.0 * p[1], 0.0])
            .collect();
        let xml = vtu_string(
            &mesh,
            &[("u", Field::Vector(&u))],
            &[
                ("von Mises <MPa> & more", Field::Scalar(&[1.5, f64::NAN])),
                ("subdomain", Field::Int(&[3, 7])),
            ],
        );
        let script = r#"
import sys, meshio, numpy as np
m = meshio.read(sys.argv[1])
assert m.points.shape == (6, 3), m.points.shape
assert len(m.cells) == 1 and m.cells[0].type == "quad", m.cells
assert m.cells[0].data.tolist() == [[0, 1, 4, 3], [1, 2, 5, 4]]
u = m.point_data["u"]
assert u.shape == (6, 3)
assert u[5, 0] == 0.2 and u[5, 1] == -1.0 / 3.0, u[5]
vm = m.cell_data["von Mises <MPa> & more"][0]
assert vm.tolist() == [1.5, 0.0], vm
assert m.cell_data["subdomain"][0].tolist() == [3, 7]
print("ok", len(m.points), sum(len(c.data) for c in m.cells))
"#;
        if let Some(out) = run_meshio("quads", &xml, script) {
            assert_eq!(out, "ok 6 2");
        }
    }

    #[test]
    fn meshio_reads_hexahedra() {
        // Two unit cubes along x: a 3 x 2 x 2 grid of points.
        let mut points = Vec::new();
        for k in 0..2 {
            for j in 0..2 {
                for i in 0..3 {
                    points.push([i as f64, j as f64, k as f64]);
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| i + 3 * j + 6 * k;
        let cells: Vec<Vec<usize>> = (0..2)
            .map(|i| {
                vec![
                    id(i, 0, 0),
                    id(i + 1, 0, 0),
                    id(i + 1, 1, 0),
                    id(i, 1, 0),
                    id(i, 0, 1),
                    id(i + 1, 0, 1),
                    id(i + 1, 1, 1),
                    id(i, 1, 1),
                ]
            })
            .collect();
        let mesh = VtuMesh {
            points: &points,
            cells: &cells,
            cell_type: CellType::Hexahedron,
        };
        let gap: Vec<f64> = points.iter().map(|p| 1e-7 * p[0] + p[2]).collect();
        let xml = vtu_string(&mesh, &[("gap", Field::Scalar(&gap))], &[]);
        let script = r#"
import sys, meshio
m = meshio.read(sys.argv[1])
assert m.cells[0].type == "hexahedron", m.cells
g = m.point_data["gap"]
assert g[2] == 2e-7 and g[11] == 1.0 + 2e-7, g
print("ok", len(m.points), sum(len(c.data) for c in m.cells))
"#;
        if let Some(out) = run_meshio("hexes", &xml, script) {
            assert_eq!(out, "ok 12 2");
        }
    }
}
