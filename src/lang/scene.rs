//! The checked scene: what a `.cso` file means, typed, validated, in SI units.
//!
//! Everything here refers to other things by index, never by name, and nothing
//! here has a span: the checker has already said everything there was to say
//! about the text. Geometry that may move with the design stays a [`Formula`];
//! everything else is a number.

use super::expr::{Arith, Cond, Formula, Func, Point};
use crate::num::Scalar;
use clap::ValueEnum;
use serde::Serialize;

/// 2D (plane strain) or 3D.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Dimension {
    #[serde(rename = "2D")]
    Two,
    #[serde(rename = "3D")]
    Three,
}

impl Dimension {
    /// Number of coordinates (and displacement components).
    pub fn n(self) -> usize {
        match self {
            Dimension::Two => 2,
            Dimension::Three => 3,
        }
    }
}

/// A whole checked scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub name: String,
    /// `title = "..."` of the scene item, for reports.
    pub title: Option<String>,
    pub dim: Dimension,
    /// Out-of-plane thickness (2D); 1 in 3D.
    pub thickness: f64,
    /// The `let` constants that evaluate to numbers, after `--set` overrides.
    pub params: Vec<Param>,
    pub materials: Vec<Material>,
    /// Design variables, flat: `a[6]` gives six entries named `a[0]` .. `a[5]`.
    pub design: Vec<DesignVar>,
    pub bodies: Vec<Body>,
    pub obstacles: Vec<Obstacle>,
    pub conditions: Vec<Condition>,
    /// Acceleration of gravity (needs `rho` on every material).
    pub gravity: Option<Vec<f64>>,
    pub glues: Vec<Glue>,
    pub contacts: Vec<Contact>,
    pub probes: Vec<Probe>,
    pub objective: Option<Objective>,
    pub constraints: Vec<Constraint>,
    pub solver: SolverSettings,
    pub sensitivity: SensitivitySettings,
    pub optimize: OptimizeSettings,
    /// What the checker warns about (the scene checks; the user should look).
    pub warnings: Vec<super::diag::Diagnostic>,
    /// The text the scene was compiled from, for the files cso writes.
    pub source: Source,
}

/// Where a scene comes from: its text and what identifies it in the files cso
/// writes (the one part of a scene with byte offsets into the text: to write the
/// scene again with other design values, see [`Source::with_design`]).
#[derive(Debug, Clone, Default)]
pub struct Source {
    /// The file as given on the command line (set by the caller; None for text
    /// compiled from memory).
    pub path: Option<String>,
    /// SHA-256 of the text, lowercase hex: the same text gives the same hash on
    /// every machine and every run.
    pub sha256: String,
    /// `--set NAME=VALUE` overrides, as given.
    pub overrides: Vec<String>,
    pub text: std::sync::Arc<str>,
    /// Byte ranges of the text to replace when writing the scene again: each
    /// design item's `init` value, and each overridden `let` value.
    pub edits: Vec<Edit>,
    /// Where the items are, so that errors found while solving point at them.
    pub places: Places,
}

/// Byte spans of the scene's items (`keyword NAME`, or `keyword SELECTION` of a
/// condition), in the order of the scene's lists: what a solve-time error
/// (overlapping bodies, a load nothing holds, an inverted element) points at.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Places {
    pub bodies: Vec<super::ast::Span>,
    pub obstacles: Vec<super::ast::Span>,
    pub contacts: Vec<super::ast::Span>,
    pub conditions: Vec<super::ast::Span>,
}

/// A place in the source text that [`Source::with_design`] rewrites.
#[derive(Debug, Clone, PartialEq)]
pub enum Edit {
    /// The `init` value of a design item: entries `first..first + size` of the
    /// design (`size` None: a scalar), written with `unit` when it has one.
    Init {
        start: usize,
        end: usize,
        first: usize,
        size: Option<usize>,
        unit: Option<String>,
    },
    /// The value of a `let` that `--set` replaced, and the value given.
    Let {
        start: usize,
        end: usize,
        value: String,
    },
    /// A `mesh = "FILE"` path, written as the absolute path of the file read
    /// (quoted), so that the rewritten scene finds it from any folder.
    MeshPath {
        start: usize,
        end: usize,
        path: String,
    },
}

impl Source {
    /// The scene's text with the design's values as the design items' `init`
    /// (and `--set` values in their `let`s), so that the text compiles to this
    /// scene started at `design`. Values are written so that they read back to
    /// the same `f64`.
    pub fn with_design(&self, design: &[f64]) -> String {
        let mut edits: Vec<(usize, usize, String)> = self
            .edits
            .iter()
            .map(|e| match e {
                Edit::Init {
                    start,
                    end,
                    first,
                    size,
                    unit,
                } => {
                    let value = |i: usize| {
                        let v = design.get(i).copied().unwrap_or(f64::NAN);
                        match unit {
                            Some(u) => format!("{v:?} {u}"),
                            None => format!("{v:?}"),
                        }
                    };
                    let text = match size {
                        None => value(*first),
                        Some(n) => format!(
                            "[{}]",
                            (*first..first + n)
                                .map(value)
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    };
                    (*start, *end, text)
                }
                Edit::Let { start, end, value } => (*start, *end, value.clone()),
                Edit::MeshPath { start, end, path } => (*start, *end, format!("\"{path}\"")),
            })
            .collect();
        edits.sort_by_key(|e| std::cmp::Reverse(e.0));
        let mut out = self.text.to_string();
        for (start, end, text) in edits {
            if start <= end
                && end <= out.len()
                && out.is_char_boundary(start)
                && out.is_char_boundary(end)
            {
                out.replace_range(start..end, &text);
            }
        }
        out
    }
}

impl Scene {
    /// Initial values of the design variables.
    pub fn design_init(&self) -> Vec<f64> {
        self.design.iter().map(|d| d.init).collect()
    }

    /// The largest ratio of Young's moduli across a `glue` (1 without one,
    /// or where every glue ties alike materials): how far the stiffness
    /// jumps across an equality row.
    pub fn glue_jump(&self) -> f64 {
        let young = |sel: &Selection| {
            let body = self.bodies.get(sel.body)?;
            Some(self.materials.get(body.material)?.young)
        };
        self.glues
            .iter()
            .filter_map(|g| Some((young(&g.primary)?, young(&g.secondary)?)))
            .map(|(a, b)| a.max(b) / a.min(b))
            .filter(|r| r.is_finite())
            .fold(1.0, f64::max)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Param {
    pub name: String,
    pub value: f64,
    /// Set with `--set` rather than in the file.
    pub overridden: bool,
    /// SI unit of the value when it was written with units (`m`, `N/m`).
    pub unit: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Material {
    pub name: String,
    /// Young's modulus (Pa).
    pub young: f64,
    /// Poisson's ratio, in (-1, 0.5).
    pub poisson: f64,
    /// Density (kg/m^3), needed only with gravity.
    pub density: Option<f64>,
    /// `formulation = ..` as written (`auto` when not); the summary shows the
    /// one used where that is B-bar.
    #[serde(skip_serializing_if = "Formulation::is_auto")]
    pub formulation: Formulation,
}

impl Material {
    /// What the elements of a body of this material get: the material, the
    /// thickness (2D) and the formulation `element` uses for it
    /// ([`crate::fem::Element::formulation`]: `auto` is B-bar from
    /// [`crate::fem::NEARLY_INCOMPRESSIBLE`] on).
    pub fn section(&self, element: crate::fem::Element, thickness: f64) -> crate::fem::Section {
        let asked = match self.formulation {
            Formulation::Auto => None,
            Formulation::Standard => Some(crate::fem::Formulation::Standard),
            Formulation::Bbar => Some(crate::fem::Formulation::Bbar),
        };
        crate::fem::Section {
            young: self.young,
            poisson: self.poisson,
            thickness,
            formulation: element.formulation(self.poisson, asked),
        }
    }
}

/// `material { formulation }`: how the elements treat the volumetric strain.
/// `auto` (the default) is `bbar` at `nu >= 0.45` and `standard` below;
/// `bbar` is mean dilatation (Hughes' B-bar), which does not lock as `nu`
/// nears 0.5; `standard` integrates every strain at every Gauss point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum Formulation {
    #[default]
    Auto,
    Standard,
    Bbar,
}

impl Formulation {
    /// Not written (serialization skips it).
    pub fn is_auto(&self) -> bool {
        *self == Formulation::Auto
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignVar {
    /// `h`, or `a[3]` for an entry of an array.
    pub name: String,
    pub init: f64,
    pub lower: f64,
    pub upper: f64,
    /// SI unit when the bounds were written with units (`m`); None: plain numbers.
    pub unit: Option<String>,
}

/// A column of a body's nodes: the face point (vertical coordinate unset) and
/// the column's bottom and top.
#[derive(Debug, Clone, Copy)]
pub struct Column<T> {
    pub face: [T; 3],
    pub bottom: T,
    pub top: T,
}

/// One structured block of one material.
#[derive(Debug, Clone)]
pub struct Body {
    pub name: String,
    pub material: usize,
    /// Extent along each axis (`x`, `y` [, `z`]); the last axis is vertical.
    pub extent: Vec<(Formula, Formula)>,
    /// Curved bottom face: height over the other coordinates (x in 2D, x and y in 3D).
    pub bottom: Option<Formula>,
    /// Curved top face, likewise.
    pub top: Option<Formula>,
    /// The curved faces as written (bottom, top), for reports.
    pub face_text: [Option<String>; 2],
    /// Elements along each axis.
    pub mesh: Vec<usize>,
    /// Subdomain cuts along each axis (each divides `mesh`).
    pub subdomains: Vec<usize>,
    /// A body read from a mesh file (`mesh = "FILE"`): its cells and cut.
    /// `extent` is then its bounding box, `mesh` empty, `subdomains` the one
    /// count, and no face is curved.
    pub imported: Option<std::sync::Arc<Imported>>,
    /// Free-form deformations of parts of the body (`morph BODY { .. }`),
    /// applied after the curved faces; their displacements add up.
    pub morphs: Vec<Morph>,
}

/// `morph BODY { x = a .. b, .., ux = EXPR, .. }`: every node of the body
/// inside the box moves by the field, whose formulas see the box's own
/// coordinates `u`, `v`, `w` in [0, 1] as coordinates 0, 1, 2 (and the
/// design); nodes outside stay.
#[derive(Debug, Clone, PartialEq)]
pub struct Morph {
    /// The box's lower and upper corners (m; unused axes 0).
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    /// The displacement per axis (m); None: zero.
    pub field: [Option<Formula>; 3],
    /// The fields as written (`uy = bezier(c, u) * (1 - v)`), for reports.
    pub text: Vec<String>,
}

impl Morph {
    /// The displacement of a node at `p` (its position before any morph):
    /// None outside the box. A node on the box's faces is inside (the field
    /// is zero there where the box cuts through the body).
    pub fn displacement<T: Scalar>(&self, p: &[T; 3], dim: usize, design: &[T]) -> Option<[T; 3]> {
        let mut at = [T::from(0.0); 3];
        for a in 0..dim {
            let (lo, hi) = (self.lo[a], self.hi[a]);
            let tol = 1e-12 * (hi - lo).abs().max(hi.abs()).max(lo.abs());
            let x = p[a].re();
            if !(x >= lo - tol && x <= hi + tol) {
                return None;
            }
            at[a] = (p[a] - lo) / (hi - lo);
        }
        let point = Point { coords: at, design };
        Some(std::array::from_fn(|a| {
            self.field[a]
                .as_ref()
                .map_or(T::from(0.0), |f| f.eval(&point))
        }))
    }

    /// Does the field depend on the design?
    pub fn uses_design(&self) -> bool {
        self.field.iter().flatten().any(Formula::uses_design)
    }
}

/// A body read from a Gmsh file, in metres, with its METIS cut.
#[derive(Debug, Clone)]
pub struct Imported {
    /// The path as written in the scene.
    pub file: String,
    /// The SHA-256 of the file's bytes (provenance).
    pub sha256: String,
    pub mesh: crate::io::msh::ImportedMesh,
    /// The subdomain of each cell (`0 .. subdomains`).
    pub part_of_cell: Vec<usize>,
    pub subdomains: usize,
    /// Pieces of subdomains METIS left disconnected, moved to a neighbour.
    pub moved_pieces: usize,
    /// Nodes over all subdomains, each subdomain with its own copy of its
    /// interface nodes.
    pub copied_nodes: usize,
}

impl Imported {
    /// The mesh cut into `parts` subdomains by METIS (fixed seed), each piece
    /// of a mesh in pieces on its own.
    ///
    /// # Errors
    /// More parts than cells, or METIS failing.
    pub fn cut(
        file: String,
        sha256: String,
        mesh: crate::io::msh::ImportedMesh,
        parts: usize,
    ) -> Result<Imported, crate::model::partition::PartitionError> {
        // A mesh in pieces (`pieces = separate`) is cut piece by piece.
        let p = if mesh.pieces > 1 {
            crate::model::partition::partition_pieces(
                mesh.kind,
                &mesh.cells,
                Some(&mesh.nodes),
                parts,
            )?
        } else {
            crate::model::partition::partition(mesh.kind, &mesh.cells, Some(&mesh.nodes), parts)?
        };
        Ok(Imported {
            file,
            sha256,
            copied_nodes: copied_nodes(&mesh.cells, &p.part_of_cell, mesh.nodes.len()),
            part_of_cell: p.part_of_cell,
            subdomains: parts,
            moved_pieces: p.moved_pieces,
            mesh,
        })
    }

    /// Facets of a face: a physical group or the whole boundary (node indices,
    /// oriented outward).
    pub fn facets(&self, face: FaceRef) -> &[Vec<usize>] {
        match face {
            FaceRef::Group(g) => self.mesh.faces.get(g).map_or(&[], |f| &f.facets),
            FaceRef::Boundary => &self.mesh.boundary,
            FaceRef::Side(_) => &[],
        }
    }

    /// The nodes of a face, sorted.
    pub fn face_nodes(&self, face: FaceRef) -> Vec<usize> {
        let mut v: Vec<usize> = self.facets(face).iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The axis a selection of a face is normal to, if its nodes are flat and
    /// normal to one: all within `1e-9` of the body's size of one coordinate.
    /// `None` also for a selection without nodes.
    pub fn flat_axis(&self, face: FaceRef, filter: Option<&Cond>, design: &[f64]) -> Option<usize> {
        let d = self.mesh.dim;
        let span = |pts: &mut dyn Iterator<Item = &[f64; 3]>, a: usize| {
            pts.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                (l.min(p[a]), h.max(p[a]))
            })
        };
        let size = (0..d)
            .map(|a| {
                let (lo, hi) = span(&mut self.mesh.nodes.iter(), a);
                hi - lo
            })
            .fold(0.0, f64::max);
        let nodes: Vec<[f64; 3]> = self
            .face_nodes(face)
            .into_iter()
            .map(|n| self.mesh.nodes[n])
            .filter(|p| filter.is_none_or(|f| f.holds(*p, design, 1e-9 * size)))
            .collect();
        (0..d).find(|&a| {
            let (lo, hi) = span(&mut nodes.iter(), a);
            !nodes.is_empty() && hi - lo <= 1e-9 * size
        })
    }

    /// The area (2D) or volume (3D) of the mesh: its cells' sum. An imported
    /// body does not move with the design, so this is a constant.
    pub fn measure(&self) -> f64 {
        let d = self.mesh.dim;
        self.mesh
            .cells
            .iter()
            .map(|c| {
                let x: Vec<f64> = c
                    .iter()
                    .flat_map(|&n| self.mesh.nodes[n][..d].to_vec())
                    .collect();
                self.mesh.kind.measure(&x).unwrap_or(0.0)
            })
            .sum()
    }

    /// The name of a face (`boundary` or the group's).
    pub fn face_name(&self, face: FaceRef) -> String {
        match face {
            FaceRef::Group(g) => self
                .mesh
                .faces
                .get(g)
                .map_or_else(String::new, |f| f.name.clone()),
            FaceRef::Boundary => "boundary".into(),
            FaceRef::Side(f) => f.name().into(),
        }
    }
}

impl Body {
    // Counts saturate: a scene too large to solve is refused by the checker's
    // memory estimate, but its summary must not overflow on the way.
    pub fn elements(&self) -> usize {
        if let Some(m) = &self.imported {
            return m.mesh.cells.len();
        }
        saturating_product(self.mesh.iter().copied())
    }

    pub fn nodes(&self) -> usize {
        if let Some(m) = &self.imported {
            return m.mesh.nodes.len();
        }
        saturating_product(self.mesh.iter().map(|m| m.saturating_add(1)))
    }

    pub fn subdomain_count(&self) -> usize {
        if let Some(m) = &self.imported {
            return m.subdomains;
        }
        saturating_product(self.subdomains.iter().copied())
    }

    /// The element kind of this body in `dim` dimensions.
    pub fn element(&self, dim: usize) -> crate::fem::Element {
        match &self.imported {
            Some(m) => m.mesh.kind,
            None => crate::fem::Element::for_dim(dim),
        }
    }

    /// The name of a face of this body.
    pub fn face_name(&self, face: FaceRef) -> String {
        match (&self.imported, face) {
            (Some(m), _) => m.face_name(face),
            (None, FaceRef::Side(f)) => f.name().into(),
            (None, _) => "boundary".into(),
        }
    }

    /// The positions of a face's nodes at a design (grid order for a
    /// structured side, node order for an imported face).
    pub fn face_points(&self, face: FaceRef, design: &[f64]) -> Vec<[f64; 3]> {
        match (&self.imported, face) {
            (Some(m), _) if self.morphs.is_empty() => m
                .face_nodes(face)
                .into_iter()
                .map(|n| m.mesh.nodes[n])
                .collect(),
            (Some(m), _) => {
                let at = self.positions(design);
                m.face_nodes(face).into_iter().map(|n| at[n]).collect()
            }
            (None, FaceRef::Side(f)) => self
                .face_indices(f)
                .into_iter()
                .map(|i| self.node(i, design))
                .collect(),
            (None, _) => Vec::new(),
        }
    }

    /// Nodes of a face (saturating), to decide whether listing them is cheap.
    pub fn face_ref_node_count(&self, face: FaceRef) -> usize {
        match (&self.imported, face) {
            (Some(m), _) => m.facets(face).len().saturating_mul(self.extent.len()),
            (None, FaceRef::Side(f)) => self.face_node_count(f),
            (None, _) => 0,
        }
    }

    /// Elements of one subdomain along each axis.
    pub fn subdomain_mesh(&self) -> Vec<usize> {
        self.mesh
            .iter()
            .zip(&self.subdomains)
            .map(|(m, s)| m / s.max(&1))
            .collect()
    }

    /// Primal unknowns: each subdomain has its own copy of its nodes (TFETI).
    pub fn primal_dofs(&self) -> usize {
        if let Some(m) = &self.imported {
            return m.copied_nodes.saturating_mul(self.extent.len());
        }
        let per = saturating_product(self.subdomain_mesh().iter().map(|h| h.saturating_add(1)));
        saturating_product([per, self.subdomain_count(), self.extent.len()])
    }

    /// Does the body's shape depend on the design (its extents, curved faces
    /// or morphs)?
    pub fn uses_design(&self) -> bool {
        self.extent
            .iter()
            .any(|(lo, hi)| lo.uses_design() || hi.uses_design())
            || self.bottom.as_ref().is_some_and(Formula::uses_design)
            || self.top.as_ref().is_some_and(Formula::uses_design)
            || self.morphs.iter().any(Morph::uses_design)
    }

    /// A node at `p` (faces applied) moved by every morph of the body: the
    /// displacements of the morphs whose box holds `p` add up.
    pub fn morphed<T: Scalar>(&self, p: [T; 3], design: &[T]) -> [T; 3] {
        let dim = self.extent.len();
        let mut out = p;
        for m in &self.morphs {
            if let Some(d) = m.displacement(&p, dim, design) {
                for a in 0..dim {
                    out[a] += d[a];
                }
            }
        }
        out
    }

    /// The smallest scaled Jacobian of the body's elements at node positions
    /// `nodes` (in [`Body::positions`]' order), or the first element folded
    /// over or squeezed against its size at `before`, the positions before the
    /// morphs ([`crate::fem::quality`]).
    pub fn quality(
        &self,
        nodes: &[[f64; 3]],
        before: &[[f64; 3]],
    ) -> Result<f64, crate::fem::quality::Folded> {
        use crate::fem::quality::worst;
        let element = self.element(self.extent.len());
        if let Some(m) = &self.imported {
            return worst(
                element,
                m.mesh.cells.iter().map(Vec::as_slice),
                nodes,
                Some(before),
            );
        }
        // The grid's cells, corners counter-clockwise (the bottom's, then the
        // top's in 3D), as the structured subdomains number them.
        let n: [usize; 3] = std::array::from_fn(|a| self.mesh.get(a).copied().unwrap_or(0));
        let at = |i: usize, j: usize, k: usize| (k * (n[1] + 1) + j) * (n[0] + 1) + i;
        let layers = if self.extent.len() == 3 { n[2] } else { 1 };
        let cells = (0..layers).flat_map(|k| {
            (0..n[1]).flat_map(move |j| {
                (0..n[0]).map(move |i| {
                    let bottom = [
                        at(i, j, k),
                        at(i + 1, j, k),
                        at(i + 1, j + 1, k),
                        at(i, j + 1, k),
                    ];
                    let mut c = bottom.to_vec();
                    if n[2] > 0 {
                        c.extend(bottom.map(|v| v + (n[0] + 1) * (n[1] + 1)));
                    }
                    c
                })
            })
        });
        let cells: Vec<Vec<usize>> = cells.collect();
        worst(
            element,
            cells.iter().map(Vec::as_slice),
            nodes,
            Some(before),
        )
    }

    /// Every node's position at a design, morphs applied: grid order
    /// (`(k * (ny + 1) + j) * (nx + 1) + i`) for a structured body, the
    /// file's order for an imported one.
    pub fn positions<T: Scalar>(&self, design: &[T]) -> Vec<[T; 3]> {
        let mut out = self.unmorphed_positions(design);
        if !self.morphs.is_empty() {
            for p in &mut out {
                *p = self.morphed(*p, design);
            }
        }
        out
    }

    /// [`Body::positions`] before the morphs: the structured grid with its
    /// curved faces, or the file's nodes.
    pub fn unmorphed_positions<T: Scalar>(&self, design: &[T]) -> Vec<[T; 3]> {
        if let Some(m) = &self.imported {
            return m.mesh.nodes.iter().map(|p| p.map(T::from)).collect();
        }
        let d = self.extent.len();
        let n: [usize; 3] = std::array::from_fn(|a| if a < d { self.mesh[a] } else { 0 });
        // The curved faces once per column, not once per node.
        let v = d - 1;
        let columns: Vec<_> = (0..=n[1] * usize::from(v == 2))
            .flat_map(|j| (0..=n[0]).map(move |i| [i, j, 0]))
            .map(|idx| self.column_t(idx, design))
            .collect();
        let mut out = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
        for k in 0..=n[2] {
            for j in 0..=n[1] {
                for i in 0..=n[0] {
                    let column = if v == 2 { j * (n[0] + 1) + i } else { i };
                    out.push(self.in_column(&columns[column], [i, j, k][v]));
                }
            }
        }
        out
    }

    /// Position of grid node `(i, j[, k])` at the given design, by the
    /// column-morphing rule: the horizontal coordinates are uniform over the
    /// extents, the vertical one interpolates linearly between the bottom and top
    /// faces of its column; then the morphs.
    pub fn node(&self, idx: [usize; 3], design: &[f64]) -> [f64; 3] {
        self.node_t(idx, design)
    }

    /// [`Body::node`] in any number type: with dual numbers seeded by a design
    /// direction, the dual parts are the exact node velocities of that direction.
    pub fn node_t<T: Scalar>(&self, idx: [usize; 3], design: &[T]) -> [T; 3] {
        let v = self.extent.len() - 1;
        self.morphed(self.in_column(&self.column_t(idx, design), idx[v]), design)
    }

    /// The column of nodes through grid index `idx` (its index along the
    /// vertical axis ignored): the face point and the column's bottom and top.
    /// Every node of a column shares them, so a pass over all nodes evaluates
    /// the curved faces once per column ([`Body::in_column`] places the nodes).
    pub fn column_t<T: Scalar>(&self, idx: [usize; 3], design: &[T]) -> Column<T> {
        let zero = T::from(0.0);
        let d = self.extent.len();
        let v = d - 1;
        let mut c = [zero; 3];
        for a in 0..v {
            let (lo, hi) = &self.extent[a];
            let at = Point {
                coords: [zero; 3],
                design,
            };
            let (lo, hi) = (lo.eval(&at), hi.eval(&at));
            c[a] = lo + (hi - lo) * (idx[a] as f64 / self.mesh[a].max(1) as f64);
        }
        let (lo, hi) = &self.extent[v];
        let fixed = Point {
            coords: [zero; 3],
            design,
        };
        let face = Point { coords: c, design };
        let bottom = self
            .bottom
            .as_ref()
            .map_or_else(|| lo.eval(&fixed), |f| f.eval(&face));
        let top = self
            .top
            .as_ref()
            .map_or_else(|| hi.eval(&fixed), |f| f.eval(&face));
        Column {
            face: c,
            bottom,
            top,
        }
    }

    /// Node `k` (along the vertical axis) of a column.
    pub fn in_column<T: Scalar>(&self, column: &Column<T>, k: usize) -> [T; 3] {
        let v = self.extent.len() - 1;
        let mut c = column.face;
        c[v] =
            column.bottom + (column.top - column.bottom) * (k as f64 / self.mesh[v].max(1) as f64);
        c
    }

    /// Grid indices of the nodes of one face, in lexicographic order.
    pub fn face_indices(&self, face: Face) -> Vec<[usize; 3]> {
        let dim = if self.extent.len() == 2 {
            Dimension::Two
        } else {
            Dimension::Three
        };
        let (axis, max) = face.axis(dim);
        let d = self.extent.len();
        let mut ranges: Vec<Vec<usize>> = (0..3)
            .map(|a| {
                if a < d {
                    (0..=self.mesh[a]).collect()
                } else {
                    vec![0]
                }
            })
            .collect();
        ranges[axis] = vec![if max { self.mesh[axis] } else { 0 }];
        let mut out = Vec::new();
        for &i in &ranges[0] {
            for &j in &ranges[1] {
                for &k in &ranges[2] {
                    out.push([i, j, k]);
                }
            }
        }
        out
    }

    /// Number of nodes on one face (saturating), to decide whether listing them is cheap.
    pub fn face_node_count(&self, face: Face) -> usize {
        let dim = if self.extent.len() == 2 {
            Dimension::Two
        } else {
            Dimension::Three
        };
        let (axis, _) = face.axis(dim);
        saturating_product(
            (0..self.extent.len())
                .filter(|a| *a != axis)
                .map(|a| self.mesh[a].saturating_add(1)),
        )
    }

    /// Is this face a curved one?
    pub fn is_curved(&self, face: Face) -> bool {
        match face {
            Face::Bottom => self.bottom.is_some(),
            Face::Top => self.top.is_some(),
            _ => false,
        }
    }
}

fn saturating_product(v: impl IntoIterator<Item = usize>) -> usize {
    v.into_iter().fold(1usize, usize::saturating_mul)
}

/// A face of a structured block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Face {
    Left,
    Right,
    Bottom,
    Top,
    Front,
    Back,
}

impl Face {
    pub const ALL: [Face; 6] = [
        Face::Left,
        Face::Right,
        Face::Bottom,
        Face::Top,
        Face::Front,
        Face::Back,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Face::Left => "left",
            Face::Right => "right",
            Face::Bottom => "bottom",
            Face::Top => "top",
            Face::Front => "front",
            Face::Back => "back",
        }
    }

    /// The axis normal to the face and whether it is the max side, in `dim` dimensions.
    pub fn axis(self, dim: Dimension) -> (usize, bool) {
        let vertical = dim.n() - 1;
        match self {
            Face::Left => (0, false),
            Face::Right => (0, true),
            Face::Front => (1, false),
            Face::Back => (1, true),
            Face::Bottom => (vertical, false),
            Face::Top => (vertical, true),
        }
    }
}

/// Nodes over all parts of a cut, each part counting every node its cells use.
fn copied_nodes(cells: &[Vec<usize>], part_of_cell: &[usize], nodes: usize) -> usize {
    // Cells sorted by part count each (node, part) pair once.
    let mut order: Vec<usize> = (0..cells.len()).collect();
    order.sort_by_key(|&c| part_of_cell[c]);
    let mut last = vec![usize::MAX; nodes];
    let mut count = 0;
    for c in order {
        let p = part_of_cell[c];
        for &n in &cells[c] {
            if last[n] != p {
                last[n] = p;
                count += 1;
            }
        }
    }
    count
}

/// A face of a body: a side of a structured block, or a face of an imported
/// body (one of its file's physical groups, or its whole boundary).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaceRef {
    Side(Face),
    /// Index into the imported mesh's [`crate::io::msh::ImportedMesh::faces`].
    Group(usize),
    Boundary,
}

impl FaceRef {
    /// The structured side, if it is one.
    pub fn side(self) -> Option<Face> {
        match self {
            FaceRef::Side(f) => Some(f),
            _ => None,
        }
    }
}

/// Nodes (and edges/faces) of one face of one body, optionally filtered.
#[derive(Debug, Clone)]
pub struct Selection {
    pub body: usize,
    pub face: FaceRef,
    pub filter: Option<Cond>,
    /// As written, for reports.
    pub text: String,
}

#[derive(Debug, Clone)]
pub enum Obstacle {
    /// A rigid plane (a line in 2D) through `point` with outward unit `normal`.
    Plane {
        name: String,
        point: Vec<Formula>,
        normal: Vec<Formula>,
    },
    /// A rigid circle/sphere; bodies touch it from outside.
    Sphere {
        name: String,
        center: Vec<Formula>,
        radius: Formula,
    },
}

impl Obstacle {
    pub fn name(&self) -> &str {
        match self {
            Obstacle::Plane { name, .. } | Obstacle::Sphere { name, .. } => name,
        }
    }
}

/// A support or a load on a selection.
#[derive(Debug, Clone)]
pub enum Condition {
    /// Zero displacement of the listed components (0 = ux, 1 = uy, 2 = uz).
    Fix {
        sel: Selection,
        components: Vec<usize>,
    },
    /// Prescribed displacement of the listed components (m).
    Displace {
        sel: Selection,
        values: Vec<(usize, f64)>,
    },
    /// Zero normal displacement.
    Symmetry { sel: Selection },
    /// Surface force per area (Pa).
    Traction { sel: Selection, value: Vec<f64> },
    /// Normal pressure (Pa), positive into the body.
    Pressure { sel: Selection, value: f64 },
}

impl Condition {
    pub fn selection(&self) -> &Selection {
        match self {
            Condition::Fix { sel, .. }
            | Condition::Displace { sel, .. }
            | Condition::Symmetry { sel }
            | Condition::Traction { sel, .. }
            | Condition::Pressure { sel, .. } => sel,
        }
    }

    pub fn keyword(&self) -> &'static str {
        match self {
            Condition::Fix { .. } => "fix",
            Condition::Displace { .. } => "displace",
            Condition::Symmetry { .. } => "symmetry",
            Condition::Traction { .. } => "traction",
            Condition::Pressure { .. } => "pressure",
        }
    }
}

#[derive(Debug, Clone)]
pub struct Glue {
    pub name: String,
    pub primary: Selection,
    pub secondary: Selection,
}

/// The primary side of a contact.
#[derive(Debug, Clone)]
pub enum Primary {
    Face(Selection),
    Obstacle(usize),
}

#[derive(Debug, Clone)]
pub struct Contact {
    pub name: String,
    pub primary: Primary,
    pub secondary: Selection,
    /// Largest initial gap that gets a contact row; `None`: a tenth of the
    /// secondary body's diagonal. The state solve widens either where the
    /// displacements carry a node without a row into the primary side.
    pub search: Option<f64>,
    /// Friction between the sides; `None`: frictionless.
    pub friction: Option<Friction>,
}

/// The friction law of a contact: what bounds the tangential traction.
#[derive(Debug, Clone)]
pub enum Friction {
    /// Coulomb: the tangential traction at most `mu` times the normal one
    /// (`friction = 0.3`).
    Coulomb(f64),
    /// Tresca: a given bound on the tangential traction (Pa), a formula over
    /// the secondary face's coordinates and the design (`slip_bound = 20 MPa`).
    Tresca(Formula),
}

#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    pub name: String,
    pub body: usize,
    pub at: Vec<f64>,
}

/// A functional of the solution and the design (objective and constraints):
/// [`Leaf`]s combined by arithmetic. [`Functional::eval`] (`lang/functional.rs`)
/// is the one walk of the arithmetic, generic over the number type; what a leaf
/// is worth depends on where it is evaluated, so each caller supplies its leaves.
#[derive(Debug, Clone, PartialEq)]
pub enum Functional {
    Leaf(Leaf),
    Neg(Box<Functional>),
    Arith(Arith, Box<Functional>, Box<Functional>),
    Pow(Box<Functional>, f64),
    Func(Func, Box<Functional>),
}

/// What a functional is built from. Every evaluation of leaves (the checker's
/// constant folding, the `f64` values, the dual-number derivatives, the
/// adjoint's linearization) matches on these without a catch-all, so a new
/// kind of functional is a variant here and a compile error wherever it needs
/// handling.
#[derive(Debug, Clone, PartialEq)]
pub enum Leaf {
    /// A number, or a formula of the design variables (no coordinates).
    Geometry(Formula),
    /// f^T u
    Compliance,
    /// 1/2 u^T K u
    Energy,
    /// Total normal force of a contact.
    ContactForce(usize),
    /// q-norm of the contact pressure over the contact face.
    PressureNorm(usize, f64),
    /// Area of a 2D body.
    Area(usize),
    /// Volume of a 3D body.
    Volume(usize),
    /// Displacement component of a probe.
    Probe(usize, usize),
    /// The value at the initial design (a constant).
    Initial(Box<Functional>),
}

impl From<Leaf> for Functional {
    fn from(leaf: Leaf) -> Functional {
        Functional::Leaf(leaf)
    }
}

#[derive(Debug, Clone)]
pub struct Objective {
    pub functional: Functional,
    pub text: String,
    /// SI unit of its value when known (`J` for compliance).
    pub unit: Option<String>,
}

/// `lhs <= rhs` or `lhs >= rhs`.
#[derive(Debug, Clone)]
pub struct Constraint {
    pub lhs: Functional,
    pub upper: bool,
    pub rhs: Functional,
    pub text: String,
    /// SI unit of its two sides when known.
    pub unit: Option<String>,
}

/// `solver { method }`: `tfeti` (every support a row, kernels known a priori) or
/// `feti` (Dirichlet dofs eliminated, kernels by pivot detection).
///
/// The words that the language and the command line accept for this enum and the
/// others below are their `ValueEnum` names (snake_case, as serialized), so each
/// is spelled in one place only. The variants carry no `///` help on purpose: it
/// would switch clap's `--help` to its long, one-option-per-paragraph layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum SolverMethod {
    Tfeti,
    Feti,
}

/// `solver { preconditioner }`. `auto` (the default) takes Dirichlet where
/// its dense Schur complements read little beside `F` and form fast (2D
/// subdomains whose `F_s` is applied by solves, H/h from about 64) or where
/// the moduli jump across a glue, else lumped where every row is an equality
/// (no contact), none elsewhere ([`crate::tfeti::precond_choice`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum Preconditioner {
    #[default]
    Auto,
    None,
    Lumped,
    Dirichlet,
}

/// `solver { local_f }`: how each subdomain's part of `F = B K^+ B^T` is
/// applied. `auto` holds `F_s = B_s K_s^+ B_s^T` as a dense matrix where its
/// `rows^2` values are fewer bytes than one solve with the subdomain's
/// Cholesky factor reads, within a quarter of the memory limit; `implicit`
/// always solves with the factor; `explicit` always holds `F_s` dense
/// (see `tfeti::local_f`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum LocalF {
    #[default]
    Auto,
    Implicit,
    Explicit,
}

impl LocalF {
    /// The name in the language and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            LocalF::Auto => "auto",
            LocalF::Implicit => "implicit",
            LocalF::Explicit => "explicit",
        }
    }
}

/// `solver { ... }`
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolverSettings {
    /// Default `tfeti`.
    pub method: SolverMethod,
    /// Relative tolerance of the dual solve; default 1e-6.
    pub tolerance: f64,
    /// Cap on Hessian applications of the whole solve; default 2000.
    pub max_iterations: usize,
    /// Dual preconditioner; default `auto`.
    pub preconditioner: Preconditioner,
    /// Dense or implicit local `F_s`; default `auto`.
    pub local_f: LocalF,
    /// Classical FETI only: relative pivot tolerance that detects the kernel; default 1e-10.
    pub eps: f64,
    /// SMALBE's tuning parameters overridden (`cso bench scaling --smalbe`);
    /// not in the language, default none.
    #[serde(skip)]
    pub smalbe: crate::qp::SmalbeOverrides,
    /// The subdomains' factor ordering; not in the language (`cso bench
    /// scaling3d --ordering`), default nested dissection where it pays.
    #[serde(skip)]
    pub ordering: crate::tfeti::settings::FactorOrdering,
    /// The coarse problem's storage; not in the language (`cso bench
    /// coarse`), default by size.
    #[serde(skip)]
    pub coarse: crate::tfeti::settings::CoarseForm,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            method: SolverMethod::Tfeti,
            tolerance: 1e-6,
            max_iterations: 2000,
            preconditioner: Preconditioner::Auto,
            local_f: LocalF::Auto,
            eps: 1e-10,
            smalbe: crate::qp::SmalbeOverrides::default(),
            ordering: Default::default(),
            coarse: Default::default(),
        }
    }
}

/// `sensitivity { method }` and `cso sensitivity --method`: `semi_analytic`
/// (exact, one solve per design variable on the state's factorization), `adjoint`
/// (exact, one adjoint solve per functional) or `finite_difference` (the baseline:
/// full state solves at perturbed designs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum SensitivityMethod {
    SemiAnalytic,
    Adjoint,
    FiniteDifference,
}

/// `sensitivity { scheme }` and `cso sensitivity --scheme`: `forward`
/// (`m + 1` solves, error `O(h)`) or `central` (`2m + 1` solves, error `O(h^2)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum Scheme {
    Forward,
    Central,
}

/// `sensitivity { ... }`
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensitivitySettings {
    /// Default `semi_analytic`.
    pub method: SensitivityMethod,
    /// Finite-difference step; default 1e-6.
    pub step: f64,
    /// Finite-difference scheme; default `central`.
    pub scheme: Scheme,
}

impl Default for SensitivitySettings {
    fn default() -> Self {
        SensitivitySettings {
            method: SensitivityMethod::SemiAnalytic,
            step: 1e-6,
            scheme: Scheme::Central,
        }
    }
}

/// `optimize { method }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ValueEnum)]
#[serde(rename_all = "snake_case")]
#[value(rename_all = "snake_case")]
pub enum OptimizeMethod {
    Mma,
}

/// `optimize { ... }`
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OptimizeSettings {
    /// Default `mma` (Svanberg's method of moving asymptotes).
    pub method: OptimizeMethod,
    /// Default 50.
    pub max_iterations: usize,
    /// KKT tolerance of the design problem; default 1e-6.
    pub tolerance: f64,
}

impl Default for OptimizeSettings {
    fn default() -> Self {
        OptimizeSettings {
            method: OptimizeMethod::Mma,
            max_iterations: 50,
            tolerance: 1e-6,
        }
    }
}
