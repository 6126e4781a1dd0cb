//! `probe NAME { body, at }`.

use super::{bounding_box, extent_text};
use crate::lang::ast::{Block, ExprKind, Ident, Span, Value};
use crate::lang::check::fields::req;
use crate::lang::check::names::Kind;
use crate::lang::check::Checker;
use crate::lang::diag::Diagnostic;
use crate::lang::scene::*;
use crate::lang::units::Dim;

impl<'a> Checker<'a> {
    /// `probe NAME { body, at }`
    pub(crate) fn probe(&mut self, name: Option<&'a Ident>, block: &'a Block) -> Option<Probe> {
        let label = name.map_or("probe".to_string(), |n| format!("probe `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let spec = [req("body", "body = NAME"), req("at", "at = (0, 0)")];
        let f = self.fields(block, &spec, &label, at, &|_| None);
        let body = f
            .get("body")
            .and_then(|fl| self.expr_of(fl, "a body name"))
            .and_then(|e| match &e.kind {
                ExprKind::Name(n) => self.lookup(Kind::Body, n, e.span),
                _ => {
                    self.error(
                        Diagnostic::new("cso::wrong-value", "`body` expects the name of a body")
                            .label(e.span, "not a name"),
                    );
                    None
                }
            });
        let point = f
            .get("at")
            .and_then(|fl| self.expr_of(fl, "a point"))
            .and_then(|e| self.vector(e, Some(Dim::LENGTH), "`at`"));
        let (body, point) = (body?, point?);
        self.probe_inside(
            body,
            &point,
            f.get("at")
                .and_then(|fl| fl.value.as_ref())
                .map_or(at, Value::span),
        )?;
        Some(Probe {
            name: name?.name.clone(),
            body,
            at: point,
        })
    }

    /// A probe point lies in its body's bounding box (at the initial design): the
    /// nearest node to a point far outside is almost certainly not what was meant.
    fn probe_inside(&mut self, b: usize, point: &[f64], span: Span) -> Option<()> {
        if !self.body_spans.get(b).is_some_and(|s| s.ok) {
            return Some(());
        }
        let body = self.bodies.get(b)?;
        let d = body.extent.len();
        if let Some(m) = &body.imported {
            // Within the bounding box, by a tenth of its size.
            let (lo, hi): (Vec<f64>, Vec<f64>) = body
                .extent
                .iter()
                .map(|(l, h)| (l.eval_f64([0.0; 3], &[]), h.eval_f64([0.0; 3], &[])))
                .unzip();
            let tol = (0..d).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) / 10.0;
            if point.len() != d
                || (0..d).all(|a| point[a] >= lo[a] - tol && point[a] <= hi[a] + tol)
            {
                return Some(());
            }
            let nodes = m.mesh.nodes.clone();
            return self.probe_outside(b, &nodes, span);
        }
        if point.len() != d || body.face_node_count(Face::Bottom) > 1_000_000 {
            return Some(());
        }
        let design = self.design_init();
        let nodes: Vec<[f64; 3]> = [Face::Bottom, Face::Top]
            .iter()
            .flat_map(|f| body.face_indices(*f))
            .map(|i| body.node(i, &design))
            .collect();
        if nodes.iter().flatten().any(|c| !c.is_finite()) {
            return Some(());
        }
        let (lo, hi) = bounding_box(&nodes, d);
        // Within one element of the box: the nearest node is then a node of the
        // body near the point (a point just below a curved face is fine).
        let tol = (0..d)
            .map(|a| (hi[a] - lo[a]) / body.mesh[a].max(1) as f64)
            .fold(0.0, f64::max);
        if (0..d).all(|a| point[a] >= lo[a] - tol && point[a] <= hi[a] + tol) {
            return Some(());
        }
        self.probe_outside(b, &nodes, span)
    }

    /// The error for a probe outside body `b`, whose nodes are these.
    fn probe_outside(&mut self, b: usize, nodes: &[[f64; 3]], span: Span) -> Option<()> {
        let body = self.bodies.get(b)?;
        let d = body.extent.len();
        let (lo, hi) = bounding_box(nodes, d);
        let spans: Vec<String> = (0..d).map(|a| extent_text(a, lo[a], hi[a])).collect();
        let name = body.name.clone();
        self.error(
            Diagnostic::new(
                "cso::probe",
                format!("the probe point lies outside body `{name}`"),
            )
            .label(span, "outside the body")
            .help(format!("body `{name}` spans {}", spans.join(", "))),
        );
        None
    }
}
