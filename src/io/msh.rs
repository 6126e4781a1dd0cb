//! Bodies from Gmsh meshes (issue 35): a MSH 4.1 file (ASCII or binary) read
//! with the `mshio` crate into an [`ImportedMesh`], a neutral description that
//! the lowering can turn into subdomains without knowing about Gmsh.
//!
//! Everything a user can get wrong in a file is a [`MeshError`] whose message
//! says what to change; no input makes this module panic. The checks are those
//! a solver needs before it starts: one element kind, no inverted or degenerate
//! element, every named face on the boundary, one connected piece.
//!
//! Two things mshio 0.4 leaves to its caller are done here: the one-line
//! `$MeshFormat` header is checked first (so that an MSH 2.2 file gets a message
//! saying how to export 4.1, and a malformed header, which makes mshio 0.4 panic,
//! gets an error), and `$PhysicalNames`, which mshio skips, is read by
//! [`physical_names`] (a few ASCII lines, ASCII in binary files too).

use crate::fem::quality::HEX_CORNERS;
use crate::lang::suggest::distance;
use mshio::{ElementType, MshFile};
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// The element kinds a body may be made of (one kind per body): the
/// elements themselves, whose facet tables (oriented outward for a cell of
/// positive measure) orient the faces read here.
pub use crate::fem::Element as CellKind;

/// The kind of a Gmsh element type, if cso takes it.
pub fn kind_of_gmsh(t: ElementType) -> Option<CellKind> {
    match t {
        ElementType::Tri3 => Some(CellKind::Tri3),
        ElementType::Qua4 => Some(CellKind::Quad4),
        ElementType::Tet4 => Some(CellKind::Tet4),
        ElementType::Hex8 => Some(CellKind::Hex8),
        _ => None,
    }
}

/// A kind in words, plural, for messages (`4-node tetrahedra`).
pub fn kind_words(k: CellKind) -> &'static str {
    match k {
        CellKind::Tri3 => "3-node triangles",
        CellKind::Quad4 => "4-node quadrilaterals",
        CellKind::Tet4 => "4-node tetrahedra",
        CellKind::Hex8 => "8-node hexahedra",
    }
}

/// A facet's nodes sorted, padded with `usize::MAX`: equal for the two cells
/// that share the facet whatever their local orders, and cheap to sort (no
/// allocation per facet on meshes of millions of cells).
pub type FacetKey = [usize; 4];

/// The key of a facet given by its (at most 4) nodes.
pub fn facet_key(nodes: &[usize]) -> FacetKey {
    let mut key = [usize::MAX; 4];
    for (k, n) in key.iter_mut().zip(nodes) {
        *k = *n;
    }
    key.sort_unstable();
    key
}

/// One cell's facet: its key, the cell and the facet's local number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct CellFacet {
    pub key: FacetKey,
    pub cell: usize,
    pub local: usize,
}

/// Every facet of every cell, sorted by key (then cell): the cells sharing a
/// facet are neighbours in the list, so boundary facets (runs of one) and the
/// dual graph (runs of two) come from one sort instead of a hash map.
pub fn sorted_facets(kind: CellKind, cells: &[Vec<usize>]) -> Vec<CellFacet> {
    let mut all = Vec::with_capacity(cells.len() * kind.facets().len());
    for (c, cell) in cells.iter().enumerate() {
        for (l, local) in kind.facets().iter().enumerate() {
            let nodes: Vec<usize> = local.iter().filter_map(|&i| cell.get(i).copied()).collect();
            all.push(CellFacet {
                key: facet_key(&nodes),
                cell: c,
                local: l,
            });
        }
    }
    all.sort_unstable();
    all
}

/// A named boundary part: a physical group of dimension `dim - 1`.
#[derive(Debug, Clone, PartialEq)]
pub struct FaceGroup {
    /// The physical group's name (its tag as text when the file names it not).
    pub name: String,
    /// Indices into [`ImportedMesh::nodes`], oriented outward like the cell
    /// facet they lie on (segments in 2D, triangles or quadrilaterals in 3D).
    pub facets: Vec<Vec<usize>>,
}

/// One body read from a mesh file, in metres, ready to be cut into subdomains.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedMesh {
    /// 2 or 3: the scene's dimension.
    pub dim: usize,
    /// Coordinates of the nodes the body's cells use, scaled by the unit factor,
    /// in the file's node order; `z = 0` in 2D.
    pub nodes: Vec<[f64; 3]>,
    pub kind: CellKind,
    /// Node indices of each cell in Gmsh's order (quadrilaterals and hexahedra
    /// as VTK).
    pub cells: Vec<Vec<usize>>,
    /// The Gmsh element id of each cell, for messages.
    pub cell_tags: Vec<u64>,
    /// The file's physical groups of dimension `dim - 1` that lie on this body,
    /// sorted by name.
    pub faces: Vec<FaceGroup>,
    /// Every boundary facet (used by exactly one cell), oriented outward, in
    /// cell order.
    pub boundary: Vec<Vec<usize>>,
    /// Nodes of the file that no element of any dimension uses (ignored; worth
    /// a note).
    pub unused_nodes: usize,
    /// Connected pieces (cells joined through shared facets): 1 unless
    /// [`ImportOptions::allow_disconnected`].
    pub pieces: usize,
}

/// What to take from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions<'a> {
    /// The scene's dimension, 2 or 3: the body is made of the elements of this
    /// dimension.
    pub dim: usize,
    /// Metres per unit of the file's coordinates (1e-3 for mm).
    pub unit: f64,
    /// A physical group of dimension `dim` to take; `None`: every element of
    /// that dimension.
    pub region: Option<&'a str>,
    /// Accept a body of several pieces (each then floats on its own).
    pub allow_disconnected: bool,
}

/// Why a mesh file cannot become a body. Each message says what to change.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshError {
    /// The file could not be read.
    Unreadable { path: PathBuf, reason: String },
    /// The file does not start with `$MeshFormat`.
    NotMsh,
    /// An MSH version other than 4.1 (as written in the file).
    Version { found: String },
    /// mshio (or the header or `$PhysicalNames` check) rejected the file.
    Parse(String),
    /// The caller passed a dimension other than 2 or 3, or a unit that is not
    /// a positive number.
    Options(String),
    /// No element of the scene's dimension; `found` counts the elements of each
    /// dimension the file has.
    NoElements {
        dim: usize,
        found: Vec<(usize, usize)>,
    },
    /// A file with elements of a higher dimension than the scene's (a 3D mesh
    /// in a 2D scene), and no `region` to say which elements to take.
    HigherDimension { dim: usize, elements: usize },
    /// No physical group of dimension `dim` with this name. `nearest`: the
    /// names of dimension `dim`, nearest first; `other_dims`: dimensions where
    /// the name exists.
    RegionNotFound {
        name: String,
        dim: usize,
        nearest: Vec<String>,
        other_dims: Vec<usize>,
    },
    /// The region exists and holds no element.
    EmptyRegion { name: String },
    /// Elements of several kinds (Gmsh type names, counts).
    MixedKinds { kinds: Vec<(String, usize)> },
    /// One element kind, but not one cso takes (e.g. second-order).
    UnsupportedKind { kind: String, count: usize },
    /// An element names a node the `$Nodes` section does not define.
    UnknownNode { element: u64, node: u64 },
    /// Two nodes with one tag (`None`: mshio merged them, the tag is lost).
    DuplicateNode { tag: Option<u64> },
    /// A node of the body with a coordinate that is not finite.
    NonFinite { node: u64 },
    /// An element whose area or volume is not positive (at some corner for
    /// quadrilaterals and hexahedra): inverted or degenerate. `centroid` is in
    /// the file's coordinates.
    Inverted { element: u64, centroid: [f64; 3] },
    /// A facet shared by more than two cells (a non-manifold mesh).
    NonManifold { cells: Vec<u64> },
    /// A face group with facets that are not on the body's boundary.
    FaceNotOnBoundary {
        name: String,
        off: usize,
        total: usize,
    },
    /// The body falls into several pieces.
    Disconnected { pieces: usize },
}

impl std::error::Error for MeshError {}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const EXPORT: &str = "export MSH 4.1 with `gmsh -format msh41` or \
             `Mesh.MshFileVersion = 4.1;` in the .geo file";
        match self {
            MeshError::Unreadable { path, reason } => {
                write!(f, "cannot read the mesh file `{}`: {reason}", path.display())
            }
            MeshError::NotMsh => write!(
                f,
                "not a Gmsh MSH file (it does not start with `$MeshFormat`); {EXPORT}"
            ),
            MeshError::Version { found } => {
                write!(f, "the mesh file is MSH {found}, cso reads MSH 4.1; {EXPORT}")
            }
            MeshError::Parse(m) => write!(f, "the mesh file is not valid MSH 4.1: {m}"),
            MeshError::Options(m) => write!(f, "{m}"),
            MeshError::NoElements { dim, found } => no_elements(f, *dim, found),
            MeshError::HigherDimension { dim, elements } => write!(
                f,
                "the mesh file holds {elements} elements of more than {dim} dimensions: is it \
                 a {}D mesh in a {dim}D scene? (name a region of dimension {dim} to take \
                 those elements only)",
                dim + 1
            ),
            MeshError::RegionNotFound {
                name,
                dim,
                nearest,
                other_dims,
            } => region_not_found(f, name, *dim, nearest, other_dims),
            MeshError::EmptyRegion { name } => write!(
                f,
                "the region `{name}` holds no element: add its volumes or surfaces to the \
                 physical group, or pick another region"
            ),
            MeshError::MixedKinds { kinds } => {
                let list: Vec<String> = kinds.iter().map(|(k, n)| format!("{n} {k}")).collect();
                write!(
                    f,
                    "a body holds one element kind, this one has {}: mesh it with one kind, or \
                     give each kind its own physical group and body (`region = ...`)",
                    list.join(", ")
                )
            }
            MeshError::UnsupportedKind { kind, count } => write!(
                f,
                "the body's {count} elements are {kind}: cso takes linear triangles and \
                 quadrilaterals (2D), tetrahedra and hexahedra (3D); mesh with \
                 `Mesh.ElementOrder = 1;`"
            ),
            MeshError::UnknownNode { element, node } => write!(
                f,
                "element {element} uses node {node}, which the file's $Nodes section does not define"
            ),
            MeshError::DuplicateNode { tag: Some(tag) } => {
                write!(f, "the file defines node {tag} twice")
            }
            MeshError::DuplicateNode { tag: None } => {
                write!(f, "the file defines a node tag twice in one node block")
            }
            MeshError::NonFinite { node } => {
                write!(f, "node {node} has a coordinate that is not a finite number")
            }
            MeshError::Inverted { element, centroid } => write!(
                f,
                "element {element} (centroid ({}, {}, {}) in the file's units) is inverted or \
                 degenerate: its area or volume is not positive; reorder its nodes or remesh",
                centroid[0], centroid[1], centroid[2]
            ),
            MeshError::NonManifold { cells } => {
                let ids: Vec<String> = cells.iter().map(u64::to_string).collect();
                write!(
                    f,
                    "elements {} share one facet (at most two may): the mesh is not a valid solid",
                    ids.join(", ")
                )
            }
            MeshError::FaceNotOnBoundary { name, off, total } => write!(
                f,
                "{off} of the {total} facets of the face group `{name}` are not on the body's \
                 boundary: a face group must lie on the body's surface"
            ),
            MeshError::Disconnected { pieces } => write!(
                f,
                "the body falls into {pieces} pieces that share no face (or edge in 2D): mesh it \
                 as one piece, give each piece its own body, or write `pieces = separate` to \
                 let each float on its own"
            ),
        }
    }
}

/// "the file has no 3D elements (it has 12 of dimension 2)".
fn no_elements(f: &mut fmt::Formatter<'_>, dim: usize, found: &[(usize, usize)]) -> fmt::Result {
    write!(f, "the mesh file has no {dim}D elements")?;
    if found.is_empty() {
        return write!(f, " (it has no elements at all)");
    }
    let list: Vec<String> = found
        .iter()
        .map(|(d, n)| format!("{n} of dimension {d}"))
        .collect();
    write!(
        f,
        " (it has {}): is the scene's dimension the mesh's?",
        list.join(", ")
    )
}

/// "no physical group `plat` of dimension 2; those of dimension 2: `plate`, ...".
fn region_not_found(
    f: &mut fmt::Formatter<'_>,
    name: &str,
    dim: usize,
    nearest: &[String],
    other_dims: &[usize],
) -> fmt::Result {
    write!(
        f,
        "the mesh file has no physical group `{name}` of dimension {dim}"
    )?;
    if let Some(d) = other_dims.first() {
        write!(
            f,
            " (`{name}` is of dimension {d}; a region is of the body's dimension)"
        )?;
    }
    if nearest.is_empty() {
        write!(
            f,
            "; it has none of dimension {dim}: leave `region` out to take every element"
        )
    } else {
        let list: Vec<String> = nearest.iter().map(|n| format!("`{n}`")).collect();
        write!(f, "; those of dimension {dim}: {}", list.join(", "))
    }
}

/// Reads a body from the MSH 4.1 file at `path`.
pub fn read_msh(path: &Path, opts: &ImportOptions) -> Result<ImportedMesh, MeshError> {
    let bytes = std::fs::read(path).map_err(|e| MeshError::Unreadable {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    parse_msh(&bytes, opts)
}

/// Reads a body from the bytes of a MSH 4.1 file (ASCII or binary).
pub fn parse_msh(bytes: &[u8], opts: &ImportOptions) -> Result<ImportedMesh, MeshError> {
    check_options(opts)?;
    check_header(bytes)?;
    let names = physical_names(bytes)?;
    let file = run_mshio(bytes)?;
    let nodes = NodeTable::new(&file)?;
    let body = select_body(&file, &names, opts)?;
    let (mut mesh, node_of) = compact(&nodes, &body, opts)?;
    check_measures(&mesh, opts.unit)?;
    let facets = sorted_facets(mesh.kind, &mesh.cells);
    mesh.boundary = boundary(&mesh, &facets)?;
    mesh.pieces = pieces(mesh.cells.len(), &facets);
    if mesh.pieces > 1 && !opts.allow_disconnected {
        return Err(MeshError::Disconnected {
            pieces: mesh.pieces,
        });
    }
    mesh.faces = face_groups(&file, &names, &mesh, &node_of)?;
    mesh.unused_nodes = nodes.unused(&file);
    Ok(mesh)
}

/// A dimension other than 2 or 3, or a unit that is not positive, is the
/// caller's mistake; an error rather than a panic all the same.
fn check_options(opts: &ImportOptions) -> Result<(), MeshError> {
    if opts.dim != 2 && opts.dim != 3 {
        return Err(MeshError::Options(format!(
            "a mesh is read for a 2D or 3D scene, not {}D",
            opts.dim
        )));
    }
    if !(opts.unit.is_finite() && opts.unit > 0.0) {
        return Err(MeshError::Options(format!(
            "the length unit of a mesh file must be a positive number of metres, not {}",
            opts.unit
        )));
    }
    Ok(())
}

/// Checks the `$MeshFormat` line: version 4.1, file type 0 or 1, a data size
/// of 1, 2, 4, 8 or 16 bytes. mshio 0.4 panics on some malformed headers and
/// says only "unsupported version" for 2.2; here each case gets its message.
fn check_header(bytes: &[u8]) -> Result<(), MeshError> {
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let rest = &bytes[start..];
    let Some(after) = rest.strip_prefix(b"$MeshFormat") else {
        return Err(MeshError::NotMsh);
    };
    let line_end = after
        .iter()
        .skip_while(|b| b.is_ascii_whitespace())
        .position(|&b| b == b'\n')
        .unwrap_or(after.len().min(200));
    let skipped = after.iter().take_while(|b| b.is_ascii_whitespace()).count();
    let line = &after[skipped..(skipped + line_end).min(after.len())];
    let line = String::from_utf8_lossy(line);
    let fields: Vec<&str> = line.split_whitespace().collect();
    let version = fields.first().copied().unwrap_or("");
    if version != "4.1" {
        let shown: String = version.chars().take(20).collect();
        return Err(MeshError::Version {
            found: if shown.is_empty() {
                "(no version)".to_string()
            } else {
                shown
            },
        });
    }
    match fields.get(1..3) {
        Some(["0" | "1", "1" | "2" | "4" | "8" | "16"]) => Ok(()),
        _ => Err(MeshError::Parse(format!(
            "the header line `{}` should read `4.1 0 8` (ASCII) or `4.1 1 8` (binary)",
            line.trim().chars().take(40).collect::<String>()
        ))),
    }
}

/// A physical group's name as `$PhysicalNames` gives it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PhysicalName {
    pub dim: usize,
    pub tag: i32,
    pub name: String,
}

/// Reads the `$PhysicalNames` section (mshio 0.4 skips it): a count, then
/// `dim tag "name"` per line. It is text in binary files too, and comes
/// before `$Nodes`, so it is looked for only there: the search stays short on
/// a large file and never reads binary node data as text. No section: no
/// names.
pub fn physical_names(bytes: &[u8]) -> Result<Vec<PhysicalName>, MeshError> {
    const START: &[u8] = b"\n$PhysicalNames";
    let find = |hay: &[u8], needle: &[u8]| hay.windows(needle.len()).position(|w| w == needle);
    let head = &bytes[..find(bytes, b"\n$Nodes").unwrap_or(bytes.len())];
    let Some(at) = find(head, START) else {
        return Ok(Vec::new());
    };
    let body = &bytes[at + START.len()..];
    let end = body
        .windows(b"$EndPhysicalNames".len())
        .position(|w| w == b"$EndPhysicalNames")
        .ok_or_else(|| MeshError::Parse("$PhysicalNames has no $EndPhysicalNames".into()))?;
    let text = std::str::from_utf8(&body[..end])
        .map_err(|_| MeshError::Parse("$PhysicalNames is not UTF-8 text".into()))?;
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let count: usize = lines
        .next()
        .and_then(|l| l.parse().ok())
        .ok_or_else(|| MeshError::Parse("$PhysicalNames does not start with a count".into()))?;
    let names: Vec<PhysicalName> = lines.map(physical_name_line).collect::<Result<_, _>>()?;
    if names.len() != count {
        return Err(MeshError::Parse(format!(
            "$PhysicalNames announces {count} names and lists {}",
            names.len()
        )));
    }
    Ok(names)
}

/// One `dim tag "name"` line of `$PhysicalNames`.
fn physical_name_line(line: &str) -> Result<PhysicalName, MeshError> {
    let bad = || {
        MeshError::Parse(format!(
            "`{line}` in $PhysicalNames is not `dim tag \"name\"`"
        ))
    };
    let mut parts = line.splitn(3, char::is_whitespace);
    let dim = parts.next().and_then(|d| d.parse().ok()).ok_or_else(bad)?;
    let tag = parts.next().and_then(|t| t.parse().ok()).ok_or_else(bad)?;
    let name = parts.next().ok_or_else(bad)?.trim();
    let name = name
        .strip_prefix('"')
        .and_then(|n| n.strip_suffix('"'))
        .unwrap_or(name);
    Ok(PhysicalName {
        dim,
        tag,
        name: name.to_string(),
    })
}

/// mshio's parse. Its own panics (a few `unwrap`s and `unimplemented!`s on
/// malformed input that [`check_header`] does not catch, arithmetic on header
/// counts) become parse errors; its message is cut to a few lines because it
/// ends with a hex dump of the rest of the file.
fn run_mshio(bytes: &[u8]) -> Result<MshFile<u64, i32, f64>, MeshError> {
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|e| short_message(&e.to_string()))
    });
    match parsed {
        Ok(Ok(file)) => Ok(file),
        Ok(Err(m)) => Err(MeshError::Parse(m)),
        Err(_) => Err(MeshError::Parse(
            "the parser stopped on malformed data (mshio panicked)".into(),
        )),
    }
}

/// mshio's message without the tail of its hex dump (at most 3 dump lines).
fn short_message(m: &str) -> String {
    const DUMP: &str = "Hex dump of the file at the error location:";
    let mut out: Vec<&str> = Vec::new();
    let mut dump_lines = None;
    for line in m.lines() {
        if let Some(n) = dump_lines.as_mut() {
            if *n >= 3 {
                break;
            }
            *n += 1;
        } else if line.trim_start().starts_with(DUMP) {
            dump_lines = Some(0);
        }
        out.push(line.trim_end());
    }
    out.join("\n")
}

/// Every node of the file: coordinates by position, position by tag.
struct NodeTable {
    coords: Vec<[f64; 3]>,
    tags: Vec<u64>,
    index: HashMap<u64, usize>,
}

impl NodeTable {
    /// Gathers the node blocks. mshio keeps a block's tags only when the file's
    /// tags are sparse; otherwise they are `min_node_tag`, `min_node_tag + 1`,
    /// ... in file order, which is how Gmsh writes them (a file whose tags are
    /// contiguous but written out of order cannot be told apart by mshio 0.4).
    fn new(file: &MshFile<u64, i32, f64>) -> Result<NodeTable, MeshError> {
        let mut table = NodeTable {
            coords: Vec::new(),
            tags: Vec::new(),
            index: HashMap::new(),
        };
        let Some(nodes) = &file.data.nodes else {
            return Ok(table);
        };
        let mut next = nodes.min_node_tag;
        for block in &nodes.node_blocks {
            let mut block_tags = vec![0u64; block.nodes.len()];
            match &block.node_tags {
                Some(map) if map.len() != block.nodes.len() => {
                    return Err(MeshError::DuplicateNode { tag: None });
                }
                Some(map) => {
                    for (&tag, &i) in map {
                        if let Some(t) = block_tags.get_mut(i) {
                            *t = tag;
                        }
                    }
                }
                None => {
                    for t in block_tags.iter_mut() {
                        *t = next;
                        next = next.saturating_add(1);
                    }
                }
            }
            for (node, tag) in block.nodes.iter().zip(block_tags) {
                if table.index.insert(tag, table.coords.len()).is_some() {
                    return Err(MeshError::DuplicateNode { tag: Some(tag) });
                }
                table.coords.push([node.x, node.y, node.z]);
                table.tags.push(tag);
            }
        }
        Ok(table)
    }

    /// Nodes that no element of any dimension uses.
    fn unused(&self, file: &MshFile<u64, i32, f64>) -> usize {
        let mut used = vec![false; self.coords.len()];
        if let Some(elements) = &file.data.elements {
            for block in &elements.element_blocks {
                for e in &block.elements {
                    for n in &e.nodes {
                        if let Some(&i) = self.index.get(n) {
                            used[i] = true;
                        }
                    }
                }
            }
        }
        used.iter().filter(|u| !**u).count()
    }
}

/// The physical tags of each entity of one dimension: entity tag -> tags.
fn entity_groups(file: &MshFile<u64, i32, f64>, dim: usize) -> HashMap<i32, Vec<i32>> {
    let Some(e) = &file.data.entities else {
        return HashMap::new();
    };
    match dim {
        0 => e
            .points
            .iter()
            .map(|p| (p.tag, p.physical_tags.clone()))
            .collect(),
        1 => e
            .curves
            .iter()
            .map(|c| (c.tag, c.physical_tags.clone()))
            .collect(),
        2 => e
            .surfaces
            .iter()
            .map(|s| (s.tag, s.physical_tags.clone()))
            .collect(),
        _ => e
            .volumes
            .iter()
            .map(|v| (v.tag, v.physical_tags.clone()))
            .collect(),
    }
}

/// The body's elements as the file gives them (Gmsh type, id, node tags),
/// before compaction.
struct Body<'f> {
    elements: Vec<(ElementType, &'f mshio::Element<u64>)>,
}

/// The elements of dimension `opts.dim`, all of them or those of the region.
fn select_body<'f>(
    file: &'f MshFile<u64, i32, f64>,
    names: &[PhysicalName],
    opts: &ImportOptions,
) -> Result<Body<'f>, MeshError> {
    let blocks: &[mshio::ElementBlock<u64, i32>] = file
        .data
        .elements
        .as_ref()
        .map_or(&[], |e| &e.element_blocks);
    let of_dim = |b: &&mshio::ElementBlock<u64, i32>| usize::try_from(b.entity_dim) == Ok(opts.dim);
    if !blocks.iter().filter(of_dim).any(|b| !b.elements.is_empty()) {
        let mut found: Vec<(usize, usize)> = Vec::new();
        for b in blocks.iter().filter(|b| !b.elements.is_empty()) {
            let d = usize::try_from(b.entity_dim).unwrap_or(0);
            match found.iter_mut().find(|(fd, _)| *fd == d) {
                Some((_, n)) => *n += b.elements.len(),
                None => found.push((d, b.elements.len())),
            }
        }
        found.sort_unstable();
        return Err(MeshError::NoElements {
            dim: opts.dim,
            found,
        });
    }
    let higher = blocks
        .iter()
        .filter(|b| usize::try_from(b.entity_dim).is_ok_and(|d| d > opts.dim))
        .map(|b| b.elements.len())
        .sum::<usize>();
    if higher > 0 && opts.region.is_none() {
        // A 3D mesh's surface triangles are not a 2D body.
        return Err(MeshError::HigherDimension {
            dim: opts.dim,
            elements: higher,
        });
    }
    let entities: Option<Vec<i32>> = match opts.region {
        None => None,
        Some(name) => Some(region_entities(file, names, name, opts.dim)?),
    };
    let elements: Vec<_> = blocks
        .iter()
        .filter(of_dim)
        .filter(|b| {
            entities
                .as_ref()
                .is_none_or(|es| es.contains(&b.entity_tag))
        })
        .flat_map(|b| b.elements.iter().map(move |e| (b.element_type, e)))
        .collect();
    if elements.is_empty() {
        return Err(MeshError::EmptyRegion {
            name: opts.region.unwrap_or_default().to_string(),
        });
    }
    Ok(Body { elements })
}

/// The entity tags of dimension `dim` in the physical group called `name`.
fn region_entities(
    file: &MshFile<u64, i32, f64>,
    names: &[PhysicalName],
    name: &str,
    dim: usize,
) -> Result<Vec<i32>, MeshError> {
    let tags: Vec<i32> = names
        .iter()
        .filter(|p| p.dim == dim && p.name == name)
        .map(|p| p.tag)
        .collect();
    if tags.is_empty() {
        let mut nearest: Vec<&PhysicalName> = names.iter().filter(|p| p.dim == dim).collect();
        nearest.sort_by_key(|p| (distance(name, &p.name), p.name.clone()));
        let mut other_dims: Vec<usize> = names
            .iter()
            .filter(|p| p.name == name)
            .map(|p| p.dim)
            .collect();
        other_dims.sort_unstable();
        other_dims.dedup();
        return Err(MeshError::RegionNotFound {
            name: name.to_string(),
            dim,
            nearest: nearest.into_iter().map(|p| p.name.clone()).collect(),
            other_dims,
        });
    }
    let mut entities: Vec<i32> = entity_groups(file, dim)
        .into_iter()
        .filter(|(_, groups)| groups.iter().any(|g| tags.contains(g)))
        .map(|(e, _)| e)
        .collect();
    entities.sort_unstable();
    Ok(entities)
}

/// One kind for the whole body, and one cso takes.
fn body_kind(body: &Body, dim: usize) -> Result<CellKind, MeshError> {
    let mut counts: Vec<(ElementType, usize)> = Vec::new();
    for (t, _) in &body.elements {
        match counts.iter_mut().find(|(ct, _)| ct == t) {
            Some((_, n)) => *n += 1,
            None => counts.push((*t, 1)),
        }
    }
    let name = |t: ElementType| match kind_of_gmsh(t) {
        Some(k) => kind_words(k).to_string(),
        None => format!("Gmsh elements of type {t:?} ({})", t as i32),
    };
    match counts.as_slice() {
        [(t, n)] => match kind_of_gmsh(*t) {
            Some(k) if k.dim() == dim => Ok(k),
            _ => Err(MeshError::UnsupportedKind {
                kind: name(*t),
                count: *n,
            }),
        },
        _ => Err(MeshError::MixedKinds {
            kinds: counts.iter().map(|(t, n)| (name(*t), *n)).collect(),
        }),
    }
}

/// Compacts the body's nodes (only those its cells use, in file order),
/// scaled to metres; `z = 0` in 2D. Also returns file node tag -> compacted
/// index, for the face groups.
fn compact(
    nodes: &NodeTable,
    body: &Body,
    opts: &ImportOptions,
) -> Result<(ImportedMesh, HashMap<u64, usize>), MeshError> {
    let kind = body_kind(body, opts.dim)?;
    let mut used = vec![false; nodes.coords.len()];
    for (_, e) in &body.elements {
        for n in &e.nodes {
            match nodes.index.get(n) {
                Some(&i) => used[i] = true,
                None => {
                    return Err(MeshError::UnknownNode {
                        element: e.element_tag,
                        node: *n,
                    })
                }
            }
        }
    }
    let mut new_index = vec![usize::MAX; nodes.coords.len()];
    let mut node_of = HashMap::new();
    let mut coords = Vec::new();
    for (i, c) in nodes.coords.iter().enumerate().filter(|(i, _)| used[*i]) {
        if !c.iter().all(|x| x.is_finite()) {
            return Err(MeshError::NonFinite {
                node: nodes.tags[i],
            });
        }
        new_index[i] = coords.len();
        node_of.insert(nodes.tags[i], coords.len());
        let z = if opts.dim == 2 { 0.0 } else { c[2] * opts.unit };
        coords.push([c[0] * opts.unit, c[1] * opts.unit, z]);
    }
    let cells = body
        .elements
        .iter()
        .map(|(_, e)| {
            e.nodes
                .iter()
                .map(|n| nodes.index.get(n).map_or(usize::MAX, |&i| new_index[i]))
                .collect()
        })
        .collect();
    let mesh = ImportedMesh {
        dim: opts.dim,
        nodes: coords,
        kind,
        cells,
        cell_tags: body.elements.iter().map(|(_, e)| e.element_tag).collect(),
        faces: Vec::new(),
        boundary: Vec::new(),
        unused_nodes: 0,
        pieces: 1,
    };
    Ok((mesh, node_of))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn det3(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// The smallest signed measure over the cell's corners (2D: in the xy plane,
/// twice the area of the corner's triangle; 3D: the corner's parallelepiped),
/// relative to the cell's size `h^dim` (h its longest node distance), so that
/// a flat cell reads about 1e-16, not 1e-40, whatever the unit.
fn relative_measure(kind: CellKind, p: &[[f64; 3]]) -> f64 {
    let mut h2: f64 = 0.0;
    for (i, a) in p.iter().enumerate() {
        for b in &p[i + 1..] {
            h2 = h2.max(sub(*a, *b).iter().map(|x| x * x).sum());
        }
    }
    let cross = |o: usize, a: usize, b: usize| {
        let (u, v) = (sub(p[a], p[o]), sub(p[b], p[o]));
        u[0] * v[1] - u[1] * v[0]
    };
    let m = match kind {
        CellKind::Tri3 => cross(0, 1, 2),
        CellKind::Quad4 => (0..4)
            .map(|k| cross(k, (k + 1) % 4, (k + 3) % 4))
            .fold(f64::INFINITY, f64::min),
        CellKind::Tet4 => det3(sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0])),
        CellKind::Hex8 => HEX_CORNERS
            .iter()
            .map(|[o, a, b, c]| det3(sub(p[*a], p[*o]), sub(p[*b], p[*o]), sub(p[*c], p[*o])))
            .fold(f64::INFINITY, f64::min),
    };
    m / h2.powf(kind.dim() as f64 / 2.0)
}

/// No inverted or degenerate cell: each must have a positive measure at every
/// corner beyond round-off (1e-12 of its size). Reports the first one by its
/// Gmsh id and centroid (in the file's units: what the user sees in Gmsh).
fn check_measures(mesh: &ImportedMesh, unit: f64) -> Result<(), MeshError> {
    for (cell, tag) in mesh.cells.iter().zip(&mesh.cell_tags) {
        let p: Vec<[f64; 3]> = cell
            .iter()
            .filter_map(|&n| mesh.nodes.get(n).copied())
            .collect();
        let m = relative_measure(mesh.kind, &p);
        if m > 1e-12 {
            continue;
        }
        let mut c = [0.0; 3];
        for q in &p {
            for a in 0..3 {
                c[a] += q[a] / (p.len() as f64 * unit);
            }
        }
        return Err(MeshError::Inverted {
            element: *tag,
            centroid: c,
        });
    }
    Ok(())
}

/// The facets used by exactly one cell, oriented outward, in cell order; a
/// facet of three or more cells is an error (no solid is made so).
fn boundary(mesh: &ImportedMesh, facets: &[CellFacet]) -> Result<Vec<Vec<usize>>, MeshError> {
    let mut once: Vec<(usize, usize)> = Vec::new();
    for run in facets.chunk_by(|a, b| a.key == b.key) {
        match run {
            [one] => once.push((one.cell, one.local)),
            [_, _] => {}
            more => {
                return Err(MeshError::NonManifold {
                    cells: more.iter().map(|f| mesh.cell_tags[f.cell]).collect(),
                })
            }
        }
    }
    once.sort_unstable();
    Ok(once
        .into_iter()
        .map(|(c, l)| oriented_facet(mesh, c, l))
        .collect())
}

/// Local facet `l` of cell `c` in node indices, oriented outward.
fn oriented_facet(mesh: &ImportedMesh, c: usize, l: usize) -> Vec<usize> {
    let local = mesh.kind.facets().get(l).copied().unwrap_or(&[]);
    local.iter().map(|&i| mesh.cells[c][i]).collect()
}

/// Connected pieces of the cells, joined through shared facets (union-find).
/// Cells touching at a node or an edge only are separate pieces: each would
/// turn about that node or edge freely.
fn pieces(n_cells: usize, facets: &[CellFacet]) -> usize {
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut parent: Vec<usize> = (0..n_cells).collect();
    for run in facets.chunk_by(|a, b| a.key == b.key) {
        if let [a, b] = run {
            let (ra, rb) = (root(&mut parent, a.cell), root(&mut parent, b.cell));
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    (0..n_cells).filter(|&i| root(&mut parent, i) == i).count()
}

/// The physical groups of dimension `dim - 1` that lie on this body, each
/// facet oriented as the boundary facet it matches. A group none of whose
/// facets has all its nodes in the body belongs to another region and is left
/// out; a group with any facet off the boundary (inside the body, or only
/// partly on it) is an error.
fn face_groups(
    file: &MshFile<u64, i32, f64>,
    names: &[PhysicalName],
    mesh: &ImportedMesh,
    node_of: &HashMap<u64, usize>,
) -> Result<Vec<FaceGroup>, MeshError> {
    let fdim = mesh.dim - 1;
    let on_boundary: HashMap<FacetKey, usize> = mesh
        .boundary
        .iter()
        .enumerate()
        .map(|(i, f)| (facet_key(f), i))
        .collect();
    let groups = group_elements(file, names, fdim);
    let mut out = Vec::new();
    for (name, elements) in groups {
        let mut facets = Vec::new();
        let (mut off, mut touching) = (0, 0);
        for e in &elements {
            let local: Option<Vec<usize>> =
                e.nodes.iter().map(|n| node_of.get(n).copied()).collect();
            let Some(local) = local else {
                off += 1;
                continue;
            };
            touching += 1;
            match on_boundary.get(&facet_key(&local)) {
                Some(&b) if local.len() == mesh.kind.facets()[0].len() => {
                    facets.push(mesh.boundary[b].clone())
                }
                _ => off += 1,
            }
        }
        if touching == 0 {
            continue;
        }
        if off > 0 {
            return Err(MeshError::FaceNotOnBoundary {
                name,
                off,
                total: elements.len(),
            });
        }
        out.push(FaceGroup { name, facets });
    }
    Ok(out)
}

/// The elements of each physical group of dimension `dim`, by name (sorted).
/// A group without a name in `$PhysicalNames` is named by its tag.
fn group_elements<'f>(
    file: &'f MshFile<u64, i32, f64>,
    names: &[PhysicalName],
    dim: usize,
) -> Vec<(String, Vec<&'f mshio::Element<u64>>)> {
    let entity_groups = entity_groups(file, dim);
    let name_of = |tag: i32| {
        names
            .iter()
            .find(|p| p.dim == dim && p.tag == tag)
            .map_or_else(|| tag.to_string(), |p| p.name.clone())
    };
    let mut groups: std::collections::BTreeMap<String, Vec<&mshio::Element<u64>>> =
        std::collections::BTreeMap::new();
    let blocks = file
        .data
        .elements
        .as_ref()
        .map_or(&[][..], |e| &e.element_blocks[..]);
    for b in blocks
        .iter()
        .filter(|b| usize::try_from(b.entity_dim) == Ok(dim))
    {
        for &g in entity_groups.get(&b.entity_tag).map_or(&[][..], |g| &g[..]) {
            groups
                .entry(name_of(g))
                .or_default()
                .extend(b.elements.iter());
        }
    }
    groups.into_iter().collect()
}

pub mod refine;

#[cfg(test)]
mod tests;
