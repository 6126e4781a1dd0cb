//! `body NAME { material, mesh = "FILE", unit, region, subdomains = N }`: a
//! body read from a Gmsh MSH 4.1 file and cut into `N` subdomains by METIS.
//! The file is read here, so that every problem with it (unreadable, wrong
//! version, unknown region, mixed or inverted elements, pieces) is an error on
//! the `mesh = ...` span, with the rest of the scene's errors.

use crate::io::msh::{ImportOptions, MeshError};
use crate::lang::ast::{Block, Expr, ExprKind, Field, Span, Value};
use crate::lang::check::fields::{opt, req, Fields, Spec};
use crate::lang::check::{BodySpans, Checker};
use crate::lang::diag::Diagnostic;
use crate::lang::expr::Formula;
use crate::lang::scene::*;
use crate::lang::units::{self, Dim};
use std::sync::Arc;

/// The file a body's `mesh` field names, if it is a string (`mesh = "a.msh"`).
pub(crate) fn mesh_file(block: &Block) -> Option<(&str, Span)> {
    block.fields.iter().find_map(|f| match &f.value {
        Some(Value::Expr(Expr {
            kind: ExprKind::Str(s),
            span,
        })) if f.name.name == "mesh" => Some((s.as_str(), *span)),
        _ => None,
    })
}

impl<'a> Checker<'a> {
    /// A body whose `mesh` names a file.
    pub(crate) fn imported_body(
        &mut self,
        mut body: Body,
        block: &'a Block,
        (file, file_span): (&str, Span),
        (label, at): (&str, Span),
    ) {
        let errors_before = self.diags.len();
        let f = self.imported_fields(block, label, at);
        if let Some(i) = f.get("material").and_then(|fl| self.body_material(fl)) {
            body.material = i;
        }
        let unit = f.get("unit").map_or(Some(1.0), |fl| self.length_unit(fl));
        let region = f.get("region").and_then(|fl| self.region_name(fl));
        let separate = f.get("pieces").is_some_and(|fl| self.pieces_apart(fl));
        let parts = f.get("subdomains").map_or(Some(1), |fl| {
            let e = self.expr_of(fl, "a subdomain count")?;
            self.integer(e, 1, "`subdomains`")
        });
        let spans = |key: &str| f.get(key).and_then(|fl| fl.value.as_ref()).map(Value::span);
        let (region_span, parts_span) = (spans("region"), spans("subdomains"));
        let key = match (unit, parts) {
            (Some(unit), Some(parts)) => {
                self.mesh_key(file, unit, region.as_deref(), separate, parts)
            }
            _ => None,
        };
        let cached = key
            .as_ref()
            .zip(self.opts.mesh_cache.as_ref())
            .and_then(|(k, c)| c.get(k));
        if let (Some(imported), Some(parts)) = (cached, parts) {
            self.keep_mesh_path(file, file_span);
            // The same file written another way: reports name it as written.
            let imported = if imported.file == file {
                imported
            } else {
                Arc::new(Imported {
                    file: file.to_string(),
                    ..(*imported).clone()
                })
            };
            body.extent = bounding_extent(&imported.mesh);
            body.subdomains = vec![parts];
            body.mesh = Vec::new();
            body.imported = Some(imported);
        } else if let (Some(unit), Some(parts)) = (unit, parts) {
            let read = self.read_mesh(file, unit, region.as_deref(), separate);
            match read {
                Ok((mesh, _)) if mesh.faces.iter().any(|g| g.name == "boundary") => {
                    self.error(
                        Diagnostic::new(
                            "cso::mesh-file",
                            "the mesh file has a physical group named `boundary`, the name of \
                             the whole boundary",
                        )
                        .label(file_span, "read from here")
                        .help("rename the group in the mesh file (Physical Surface or Curve)"),
                    );
                }
                Ok((mesh, sha256)) => {
                    self.keep_mesh_path(file, file_span);
                    if let Some(imported) = self.cut(mesh, parts, parts_span.unwrap_or(file_span)) {
                        let imported = Imported {
                            file: file.to_string(),
                            sha256,
                            ..imported
                        };
                        body.extent = bounding_extent(&imported.mesh);
                        body.subdomains = vec![parts];
                        body.mesh = Vec::new();
                        let imported = Arc::new(imported);
                        if let (Some(k), Some(c)) = (key, self.opts.mesh_cache.as_ref()) {
                            c.put(k, imported.clone());
                        }
                        body.imported = Some(imported);
                    }
                }
                Err(e) => self.mesh_error(&e, file, file_span, region_span),
            }
        }
        self.body_spans.push(BodySpans {
            name: at,
            mesh: Some(file_span),
            faces: [None, None],
            ok: self.diags.len() == errors_before,
        });
        self.bodies.push(body);
    }

    fn imported_fields(&mut self, block: &'a Block, label: &str, at: Span) -> Fields<'a> {
        let spec: Vec<Spec> = vec![
            req("material", "material = NAME"),
            req("mesh", "mesh = \"part.msh\""),
            opt("unit", "unit = mm"),
            opt("region", "region = \"NAME\""),
            opt("subdomains", "subdomains = 8"),
            opt("pieces", "pieces = separate"),
        ];
        let hint = |n: &str| match n {
            "x" | "y" | "z" | "bottom" | "top" => Some(format!(
                "a body read from a mesh file takes its shape from the file; remove `{n}` \
                 (or drop `mesh = \"...\"` for a structured block)"
            )),
            "units" | "scale" => Some("the file's length unit is written `unit = mm`".into()),
            "group" | "physical" => {
                Some("the physical group to take is written `region = \"NAME\"`".into())
            }
            "subdomain" | "parts" | "cuts" => {
                Some("the subdomain count is written `subdomains = 8`".into())
            }
            _ => None,
        };
        self.fields(block, &spec, label, at, &hint)
    }

    /// `unit = mm`: metres per unit of the file's coordinates.
    fn length_unit(&mut self, fl: &'a Field) -> Option<f64> {
        let e = self.expr_of(fl, "a length unit")?;
        let name = match &e.kind {
            ExprKind::Name(n) => n.as_str(),
            _ => "",
        };
        match units::unit(name) {
            Some((factor, dim)) if dim == Dim::LENGTH => Some(factor),
            _ => {
                let lengths: Vec<&str> = units::known_units()
                    .into_iter()
                    .filter(|u| units::unit(u).is_some_and(|(_, d)| d == Dim::LENGTH))
                    .collect();
                let near: Vec<&str> = units::nearest_units(name)
                    .into_iter()
                    .filter(|u| lengths.contains(u))
                    .collect();
                let help = match near.first() {
                    Some(u) => format!("did you mean `{u}`?"),
                    None => format!("the length units are {}", lengths.join(", ")),
                };
                self.error(
                    Diagnostic::new(
                        "cso::unit",
                        format!(
                            "`unit` expects a length unit, found `{}`",
                            self.text(e.span)
                        ),
                    )
                    .label(e.span, "not a length unit")
                    .help(help),
                );
                None
            }
        }
    }

    /// `pieces = separate`: a mesh in several pieces is taken as they are,
    /// each floating on its own (held by its own supports and contacts).
    fn pieces_apart(&mut self, fl: &'a Field) -> bool {
        let Some(e) = self.expr_of(fl, "`separate`") else {
            return false;
        };
        if matches!(&e.kind, ExprKind::Name(n) if n == "separate") {
            return true;
        }
        self.error(
            Diagnostic::new("cso::wrong-value", "`pieces` takes one value, `separate`")
                .label(e.span, "expected `separate`")
                .help(
                    "write `pieces = separate` to take a mesh in several pieces, each \
                     floating on its own; leave it out for a mesh in one piece",
                ),
        );
        false
    }

    /// `region = "NAME"`.
    fn region_name(&mut self, fl: &'a Field) -> Option<String> {
        let e = self.expr_of(fl, "a physical group's name")?;
        if let ExprKind::Str(s) = &e.kind {
            return Some(s.clone());
        }
        self.error(
            Diagnostic::new(
                "cso::wrong-value",
                "`region` expects the name of a physical group, in quotes",
            )
            .label(e.span, "not a quoted name")
            .help(format!("write `region = \"{}\"`", self.text(e.span))),
        );
        None
    }

    /// The file's path relative to the scene's folder.
    fn mesh_path(&self, file: &str) -> std::path::PathBuf {
        match &self.opts.base_dir {
            Some(dir) => dir.join(file),
            None => std::path::PathBuf::from(file),
        }
    }

    /// A scene rewritten elsewhere (`best.cso`) names the file by its absolute
    /// path (a path with a `"` cannot be written, and stays as it was).
    fn keep_mesh_path(&mut self, file: &str, span: Span) {
        let Ok(path) = std::fs::canonicalize(self.mesh_path(file)) else {
            return;
        };
        let path = path.to_string_lossy().to_string();
        if !path.contains('"') && !path.contains('\n') {
            self.edits.push(crate::lang::scene::Edit::MeshPath {
                start: span.start,
                end: span.end,
                path,
            });
        }
    }

    /// The cache key of a mesh file as asked for; None where the file
    /// cannot be looked at (reading it says why).
    fn mesh_key(
        &self,
        file: &str,
        unit: f64,
        region: Option<&str>,
        separate: bool,
        parts: usize,
    ) -> Option<crate::lang::check::MeshKey> {
        self.opts.mesh_cache.as_ref()?;
        let path = std::fs::canonicalize(self.mesh_path(file)).ok()?;
        let meta = std::fs::metadata(&path).ok()?;
        Some(crate::lang::check::MeshKey {
            path,
            len: meta.len(),
            modified: meta.modified().ok(),
            dim: self.dim.n(),
            unit: unit.to_bits(),
            region: region.map(str::to_string),
            separate,
            parts,
        })
    }

    /// Reads the file, relative to the scene's folder; its bytes' SHA-256.
    fn read_mesh(
        &self,
        file: &str,
        unit: f64,
        region: Option<&str>,
        separate: bool,
    ) -> Result<(crate::io::msh::ImportedMesh, String), MeshError> {
        let path = self.mesh_path(file);
        let bytes = std::fs::read(&path).map_err(|e| MeshError::Unreadable {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        let opts = ImportOptions {
            dim: self.dim.n(),
            unit,
            region,
            allow_disconnected: separate,
        };
        let mesh = crate::io::msh::parse_msh(&bytes, &opts)?;
        Ok((mesh, super::super::sha256_hex(&bytes)))
    }

    /// Cuts the mesh into `parts` subdomains (METIS, fixed seed).
    fn cut(
        &mut self,
        mesh: crate::io::msh::ImportedMesh,
        parts: usize,
        span: Span,
    ) -> Option<Imported> {
        match Imported::cut(String::new(), String::new(), mesh, parts) {
            Ok(imported) => Some(imported),
            Err(e) => {
                self.error(
                    Diagnostic::new("cso::subdomains", e.to_string())
                        .label(span, format!("{parts} subdomains")),
                );
                None
            }
        }
    }

    fn mesh_error(&mut self, e: &MeshError, file: &str, file_span: Span, region: Option<Span>) {
        let (span, label) = match (e, region) {
            (MeshError::RegionNotFound { .. } | MeshError::EmptyRegion { .. }, Some(r)) => {
                (r, "this region")
            }
            (MeshError::Unreadable { .. }, _) => (file_span, "this file"),
            _ => (file_span, "read from here"),
        };
        let mut d = Diagnostic::new("cso::mesh-file", e.to_string()).label(span, label);
        if let MeshError::Unreadable { path, .. } = e {
            d = d.help(format!(
                "the path `{file}` is taken relative to the scene's folder: `{}` was tried",
                path.display()
            ));
        }
        self.error(d);
    }
}

/// The bounding box of a mesh's nodes, as constant extents.
fn bounding_extent(mesh: &crate::io::msh::ImportedMesh) -> Vec<(Formula, Formula)> {
    (0..mesh.dim)
        .map(|a| {
            let (lo, hi) = mesh
                .nodes
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                    (l.min(p[a]), h.max(p[a]))
                });
            (Formula::Const(lo), Formula::Const(hi))
        })
        .collect()
}
