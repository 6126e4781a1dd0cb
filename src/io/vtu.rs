//! VTK XML unstructured grids (`.vtu`) and ParaView collections (`.pvd`).
//!
//! Meshes, displacements, stresses, contact pressures and the active set of each
//! iteration are looked at in ParaView, so they are written in the format it
//! reads natively. The format is short enough to write by hand (`vtkio` writes
//! wrong attributes for unstructured pieces).
//!
//! Two encodings of the arrays: [`Encoding::Binary`] (what cso writes: inline
//! base64, about a third of the ASCII size of a 640 x 640 mesh and exact) and
//! [`Encoding::Ascii`] (diffable and checkable by eye, for small meshes and tests).
//!
//! # Wire format
//! ```xml
//! <VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
//!   <UnstructuredGrid><Piece NumberOfPoints=".." NumberOfCells="..">
//!     <PointData> DataArray per field </PointData>
//!     <CellData> DataArray per field </CellData>
//!     <Points> Float64 x 3 </Points>
//!     <Cells> Int64 connectivity, Int64 offsets, UInt8 types </Cells>
//!   </Piece></UnstructuredGrid>
//! </VTKFile>
//! ```
//! A binary `DataArray` (`format="binary"`) holds one base64 block (RFC 4648,
//! padded) of the little-endian UInt64 byte count of the data followed by the
//! data, little-endian: VTK's inline binary layout for uncompressed arrays with
//! `header_type="UInt64"`. ASCII floats are written so that they read back to the
//! same `f64` (Rust's shortest round-trip formatting). Non-finite floats are
//! written as `0` in both encodings: the caller guarantees finite values, and this
//! last guard exists because a single `nan` makes some readers reject the whole
//! file, which would hide every other field of that iteration. Names are
//! XML-escaped.
//!
//! The mesh is general: points with three coordinates and a flat connectivity of
//! one cell type (its VTK id and node count), so quadrilaterals (9) and
//! hexahedra (12) go through the same code.

use std::fmt::Write;

/// The VTK cell type shared by all cells of a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellType {
    /// Bilinear quadrilateral (`VTK_QUAD` = 9), nodes counter-clockwise.
    Quad,
    /// Trilinear hexahedron (`VTK_HEXAHEDRON` = 12), bottom face
    /// counter-clockwise then top face in the same order.
    Hexahedron,
    /// Linear triangle (`VTK_TRIANGLE` = 5), counter-clockwise.
    Triangle,
    /// Linear tetrahedron (`VTK_TETRA` = 10), positive volume.
    Tetrahedron,
}

impl CellType {
    /// The cell type number in VTK's `types` array.
    pub fn vtk_id(self) -> u8 {
        match self {
            CellType::Quad => 9,
            CellType::Hexahedron => 12,
            CellType::Triangle => 5,
            CellType::Tetrahedron => 10,
        }
    }

    /// The cell type of an element kind (the node orders agree).
    pub fn of(element: crate::fem::Element) -> CellType {
        use crate::fem::Element;
        match element {
            Element::Quad4 => CellType::Quad,
            Element::Hex8 => CellType::Hexahedron,
            Element::Tri3 => CellType::Triangle,
            Element::Tet4 => CellType::Tetrahedron,
        }
    }

    /// Nodes per cell.
    pub fn nodes(self) -> usize {
        match self {
            CellType::Quad => 4,
            CellType::Hexahedron => 8,
            CellType::Triangle => 3,
            CellType::Tetrahedron => 4,
        }
    }
}

/// A mesh to write. 2D meshes pass `z = 0`: VTK points always have three
/// coordinates.
#[derive(Debug, Clone, Copy)]
pub struct VtuMesh<'a> {
    pub points: &'a [[f64; 3]],
    /// Point indices of every cell, `cell_type.nodes()` per cell, cell after
    /// cell, each cell in VTK order.
    pub connectivity: &'a [usize],
    pub cell_type: CellType,
}

impl VtuMesh<'_> {
    /// Number of cells (whole cells of the connectivity).
    pub fn n_cells(&self) -> usize {
        self.connectivity.len() / self.cell_type.nodes()
    }
}

/// How the arrays are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Text, one number per token.
    Ascii,
    /// Inline base64 of a UInt64 byte count and the little-endian data.
    Binary,
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
/// cell field one per cell, and the connectivity whole cells of valid point
/// indices: these are facts about the caller's own arrays, not user input.
/// A field of the wrong length is a bug that debug builds stop on; release
/// builds leave that field out rather than write a file ParaView rejects.
pub fn vtu_string(
    mesh: &VtuMesh,
    point_data: &[(&str, Field)],
    cell_data: &[(&str, Field)],
    encoding: Encoding,
) -> String {
    let n_points = mesh.points.len();
    let per = mesh.cell_type.nodes();
    debug_assert!(
        mesh.connectivity.len() % per == 0 && mesh.connectivity.iter().all(|&i| i < n_points),
        "the connectivity must be whole cells of {per} valid point indices"
    );
    let connectivity = &mesh.connectivity[..mesh.n_cells() * per];
    let n_cells = mesh.n_cells();

    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n",
    );
    s.push_str("  <UnstructuredGrid>\n");
    // `write!` into a String cannot fail; the results are ignored for that reason.
    let _ = writeln!(
        s,
        "    <Piece NumberOfPoints=\"{n_points}\" NumberOfCells=\"{n_cells}\">"
    );

    let mut w = Writer { s, encoding };
    w.fields("PointData", point_data, n_points);
    w.fields("CellData", cell_data, n_cells);

    w.s.push_str("      <Points>\n");
    w.array(
        "Float64",
        "Points",
        3,
        Values::Floats(mesh.points.as_flattened()),
    );
    w.s.push_str("      </Points>\n");

    w.s.push_str("      <Cells>\n");
    let conn: Vec<i64> = connectivity.iter().map(|&i| i as i64).collect();
    w.array("Int64", "connectivity", 1, Values::Ints(&conn));
    let offsets: Vec<i64> = (1..=n_cells).map(|c| (c * per) as i64).collect();
    w.array("Int64", "offsets", 1, Values::Ints(&offsets));
    let types = vec![mesh.cell_type.vtk_id(); n_cells];
    w.array("UInt8", "types", 1, Values::Bytes(&types));
    w.s.push_str("      </Cells>\n");

    let mut s = w.s;
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

/// The parallel file (`.pvtu`) over pieces written one per rank: the
/// fields' names and types (taken from `point_data` and `cell_data`, whose
/// values are not read) and each piece's file, relative to the `.pvtu`'s
/// directory. ParaView opens it as one data set.
pub fn pvtu_string(
    point_data: &[(&str, Field)],
    cell_data: &[(&str, Field)],
    pieces: &[String],
) -> String {
    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str(
        "<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n",
    );
    s.push_str("  <PUnstructuredGrid GhostLevel=\"0\">\n");
    let declare = |s: &mut String, tag: &str, fields: &[(&str, Field)]| {
        let _ = writeln!(s, "    <{tag}>");
        for (name, field) in fields {
            let (ty, comps) = match field {
                Field::Scalar(_) => ("Float64", ""),
                Field::Vector(_) => ("Float64", " NumberOfComponents=\"3\""),
                Field::Int(_) => ("Int64", ""),
            };
            let _ = writeln!(
                s,
                "      <PDataArray type=\"{ty}\" Name=\"{}\"{comps}/>",
                xml_escape(name)
            );
        }
        let _ = writeln!(s, "    </{tag}>");
    };
    declare(&mut s, "PPointData", point_data);
    declare(&mut s, "PCellData", cell_data);
    s.push_str("    <PPoints>\n");
    s.push_str("      <PDataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"/>\n");
    s.push_str("    </PPoints>\n");
    for piece in pieces {
        let _ = writeln!(s, "    <Piece Source=\"{}\"/>", xml_escape(piece));
    }
    s.push_str("  </PUnstructuredGrid>\n");
    s.push_str("</VTKFile>\n");
    s
}

/// The values of one `DataArray`.
enum Values<'a> {
    Floats(&'a [f64]),
    Ints(&'a [i64]),
    Bytes(&'a [u8]),
}

/// The file being written and how its arrays are encoded.
struct Writer {
    s: String,
    encoding: Encoding,
}

impl Writer {
    /// One `<PointData>` or `<CellData>` block; fields whose length is not `n`
    /// are left out (see [`vtu_string`]).
    fn fields(&mut self, tag: &str, fields: &[(&str, Field)], n: usize) {
        let _ = writeln!(self.s, "      <{tag}>");
        for (name, field) in fields {
            debug_assert_eq!(field.len(), n, "{tag} field {name:?} has the wrong length");
            if field.len() != n {
                continue;
            }
            match field {
                Field::Scalar(v) => self.array("Float64", name, 1, Values::Floats(v)),
                Field::Vector(v) => {
                    self.array("Float64", name, 3, Values::Floats(v.as_flattened()))
                }
                Field::Int(v) => self.array("Int64", name, 1, Values::Ints(v)),
            }
        }
        let _ = writeln!(self.s, "      </{tag}>");
    }

    /// One `DataArray`. One-component arrays carry no NumberOfComponents: VTK
    /// defaults it to 1, and meshio then reads a flat array instead of an n x 1
    /// matrix.
    fn array(&mut self, ty: &str, name: &str, comps: usize, values: Values) {
        let comps = if comps > 1 {
            format!(" NumberOfComponents=\"{comps}\"")
        } else {
            String::new()
        };
        let format = match self.encoding {
            Encoding::Ascii => "ascii",
            Encoding::Binary => "binary",
        };
        let _ = writeln!(
            self.s,
            "        <DataArray type=\"{ty}\" Name=\"{}\"{comps} format=\"{format}\">",
            xml_escape(name)
        );
        match self.encoding {
            Encoding::Ascii => {
                let per_line = if comps.is_empty() { 8 } else { 3 };
                match values {
                    Values::Floats(v) => {
                        v.chunks(per_line).for_each(|c| push_floats(&mut self.s, c))
                    }
                    Values::Ints(v) => v
                        .chunks(16)
                        .for_each(|c| push_ints(&mut self.s, c.iter().copied())),
                    Values::Bytes(v) => v
                        .chunks(16)
                        .for_each(|c| push_ints(&mut self.s, c.iter().map(|&b| i64::from(b)))),
                }
            }
            Encoding::Binary => {
                let data: Vec<u8> = match values {
                    Values::Floats(v) => v
                        .iter()
                        .flat_map(|x| (if x.is_finite() { *x } else { 0.0 }).to_le_bytes())
                        .collect(),
                    Values::Ints(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
                    Values::Bytes(v) => v.to_vec(),
                };
                let mut block = Vec::with_capacity(8 + data.len());
                block.extend_from_slice(&(data.len() as u64).to_le_bytes());
                block.extend_from_slice(&data);
                self.s.push_str("          ");
                base64_into(&mut self.s, &block);
                self.s.push('\n');
            }
        }
        self.s.push_str("        </DataArray>\n");
    }
}

/// Standard base64 (RFC 4648 alphabet, `=` padding), appended to `out`. Twenty
/// lines instead of a dependency; tested against the RFC's vectors.
pub fn base64_into(out: &mut String, bytes: &[u8]) {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    out.reserve(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
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
pub(crate) mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::process::Command;

    /// Two unit quads side by side: points 0..6 on a 3 x 2 grid.
    fn two_quads() -> (Vec<[f64; 3]>, Vec<usize>) {
        let points = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [2.0, 1.0, 0.0],
        ];
        let cells = vec![0, 1, 4, 3, 1, 2, 5, 4];
        (points, cells)
    }

    /// [`two_quads`] with `u = (x / 10, -y / 3, 0)`, a cell scalar `name` of
    /// (1.5, NaN) and the subdomain ids given.
    fn two_quads_vtu(name: &str, subdomains: [i64; 2], encoding: Encoding) -> String {
        let (points, cells) = two_quads();
        let mesh = VtuMesh {
            points: &points,
            connectivity: &cells,
            cell_type: CellType::Quad,
        };
        let u: Vec<[f64; 3]> = points
            .iter()
            .map(|p| [0.1 * p[0], -1.0 / 3.0 * p[1], 0.0])
            .collect();
        vtu_string(
            &mesh,
            &[("u", Field::Vector(&u))],
            &[
                (name, Field::Scalar(&[1.5, f64::NAN])),
                ("subdomain", Field::Int(&subdomains)),
            ],
            encoding,
        )
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
            connectivity: &cells,
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
            Encoding::Ascii,
        );
        assert!(xml.starts_with("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\""));
        assert!(xml.contains("version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\""));
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
            connectivity: &cells,
            cell_type: CellType::Quad,
        };
        let xml = vtu_string(
            &mesh,
            &[],
            &[("p", Field::Scalar(&[f64::NAN, 1e300]))],
            Encoding::Ascii,
        );
        assert_eq!(array_tokens(&xml, "p"), ["0", "1e300"]);
        assert!(!xml.to_lowercase().contains("nan"));
        assert!(!xml.contains("inf"));
    }

    #[test]
    fn names_are_escaped() {
        let (points, cells) = two_quads();
        let mesh = VtuMesh {
            points: &points,
            connectivity: &cells,
            cell_type: CellType::Quad,
        };
        let xml = vtu_string(
            &mesh,
            &[],
            &[("a<b> & \"c\"", Field::Int(&[1, 2]))],
            Encoding::Binary,
        );
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

    #[test]
    fn base64_matches_rfc_4648() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            let mut s = String::new();
            base64_into(&mut s, plain.as_bytes());
            assert_eq!(s, coded, "{plain:?}");
        }
        let mut s = String::new();
        base64_into(&mut s, &[0xfb, 0xff, 0xfe]);
        assert_eq!(s, "+//+");
    }

    /// Standard base64 back to bytes (the tests' own decoder, independent of
    /// the encoder; the plot tests read the embedded PNG with it too).
    pub(crate) fn decode64(text: &str) -> Vec<u8> {
        let val = |c: u8| match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        };
        let mut out = Vec::new();
        for quad in text.trim().as_bytes().chunks(4) {
            let pad = quad.iter().filter(|&&c| c == b'=').count();
            let n = quad
                .iter()
                .map(|&c| if c == b'=' { 0 } else { u32::from(val(c)) })
                .fold(0u32, |n, v| (n << 6) | v);
            out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
        }
        out
    }

    /// The data of a binary array: checks the UInt64 byte count header.
    pub(crate) fn binary_array(xml: &str, name: &str) -> Vec<u8> {
        let tokens = array_tokens(xml, name);
        assert_eq!(tokens.len(), 1, "one base64 block");
        let block = decode64(tokens[0]);
        let n = u64::from_le_bytes(block[..8].try_into().unwrap()) as usize;
        assert_eq!(
            n,
            block.len() - 8,
            "{name}: the header counts the data bytes"
        );
        block[8..].to_vec()
    }

    /// The `f64` values of a binary array.
    pub(crate) fn binary_floats(xml: &str, name: &str) -> Vec<f64> {
        binary_array(xml, name)
            .chunks(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }

    /// The `i64` values of a binary array.
    pub(crate) fn binary_ints(xml: &str, name: &str) -> Vec<i64> {
        binary_array(xml, name)
            .chunks(8)
            .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }

    #[test]
    fn binary_arrays_decode_to_the_ascii_values() {
        let write = |encoding| two_quads_vtu("vm", [3, -7], encoding);
        let (ascii, binary) = (write(Encoding::Ascii), write(Encoding::Binary));
        assert!(binary.contains("header_type=\"UInt64\""));
        assert_eq!(binary.matches("format=\"binary\"").count(), 7);
        assert!(!binary.contains("format=\"ascii\""));
        let floats = |b: Vec<u8>| -> Vec<f64> {
            b.chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        let ints = |b: Vec<u8>| -> Vec<i64> {
            b.chunks(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        for name in ["u", "vm", "Points"] {
            let text: Vec<f64> = array_tokens(&ascii, name)
                .iter()
                .map(|t| t.parse().unwrap())
                .collect();
            assert_eq!(floats(binary_array(&binary, name)), text, "{name}");
        }
        for name in ["subdomain", "connectivity", "offsets"] {
            let text: Vec<i64> = array_tokens(&ascii, name)
                .iter()
                .map(|t| t.parse().unwrap())
                .collect();
            assert_eq!(ints(binary_array(&binary, name)), text, "{name}");
        }
        assert_eq!(binary_array(&binary, "types"), [9, 9]);
        assert_eq!(floats(binary_array(&binary, "vm")), [1.5, 0.0], "NaN is 0");
    }

    /// Runs `script` (Python, with the file path in `sys.argv[1]`) on `xml`
    /// written to a temporary file; `None` when Python or meshio is missing, so
    /// machines without them skip the check instead of failing.
    fn run_meshio(test: &str, xml: &str, script: &str) -> Option<String> {
        // CI points CSO_PYTHON at the system interpreter that has meshio.
        let python = std::env::var("CSO_PYTHON").unwrap_or_else(|_| "python3".to_string());
        let has_meshio = Command::new(&python)
            .args(["-c", "import meshio"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false);
        if !has_meshio {
            eprintln!(
                "SKIPPED {test}: {python} with meshio is not available (apt install python3-meshio)"
            );
            return None;
        }
        let path: PathBuf =
            std::env::temp_dir().join(format!("cso-vtu-{}-{test}.vtu", std::process::id()));
        crate::io::atomic::write_atomic(&path, xml.as_bytes()).unwrap();
        let out = Command::new(&python)
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
        let write = |encoding| two_quads_vtu("von Mises <MPa> & more", [3, 7], encoding);
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
        for (name, encoding) in [
            ("quads", Encoding::Ascii),
            ("quads-binary", Encoding::Binary),
        ] {
            if let Some(out) = run_meshio(name, &write(encoding), script) {
                assert_eq!(out, "ok 6 2", "{name}");
            }
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
        let cells: Vec<usize> = (0..2)
            .flat_map(|i| {
                [
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
            connectivity: &cells,
            cell_type: CellType::Hexahedron,
        };
        let gap: Vec<f64> = points.iter().map(|p| 1e-7 * p[0] + p[2]).collect();
        let xml = vtu_string(
            &mesh,
            &[("gap", Field::Scalar(&gap))],
            &[],
            Encoding::Binary,
        );
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
