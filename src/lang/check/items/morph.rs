//! `morph BODY { x = a .. b, y = .. [, z = ..], ux = EXPR, uy = EXPR [, uz = EXPR] }`:
//! a free-form deformation of the part of a body inside a box.

use super::{bounding_box, extent_text};
use crate::lang::ast::{Block, Ident, Span};
use crate::lang::check::fields::{opt, req, Spec};
use crate::lang::check::names::Kind;
use crate::lang::check::Checker;
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::*;
use crate::lang::units::Dim;

const AXES: [&str; 3] = ["x", "y", "z"];
const FIELDS: [&str; 3] = ["ux", "uy", "uz"];
const BOX: [&str; 3] = ["u", "v", "w"];

/// Bodies with more nodes than this are not checked node by node (the
/// memory estimate judges them first; the solve checks every element).
pub(super) const NODE_CHECKS: usize = 2_000_000;

/// Points per axis along which a box face is sampled for a field that does
/// not vanish there.
const FACE_SAMPLES: usize = 9;

impl<'a> Checker<'a> {
    /// `morph BODY { .. }`: the body's name, the box (every axis of the
    /// scene), the fields (lengths over the box's `u`, `v`, `w` and the
    /// design). Errors: an unknown body, a box that holds none of its nodes;
    /// warnings: a field without design variables (a fixed deformation), a
    /// field that does not vanish where the box cuts through the body.
    pub(crate) fn morph(&mut self, keyword: &'a Ident, name: Option<&'a Ident>, block: &'a Block) {
        let d = self.dim.n();
        let Some(name) = name else {
            self.error(
                Diagnostic::new("cso::missing-name", "a morph needs the name of its body")
                    .label(keyword.span, "no body named after this")
                    .help("write `morph BODY { x = .., y = .., uy = .. }`"),
            );
            return;
        };
        let label = format!("morph `{}`", name.name);
        let body = self.lookup(Kind::Body, &name.name, name.span);
        let f = self.fields(block, &morph_spec(d), &label, name.span, &|n| {
            morph_hint(n, d)
        });
        let mut morph = Morph {
            lo: [0.0; 3],
            hi: [0.0; 3],
            field: [None, None, None],
            text: Vec::new(),
        };
        let mut ok = true;
        for (a, key) in AXES.iter().enumerate().take(d) {
            match f.get(key).and_then(|fl| self.box_range(fl, key)) {
                Some((lo, hi)) => (morph.lo[a], morph.hi[a]) = (lo, hi),
                None => ok = false,
            }
        }
        let mut written: Vec<(usize, Span)> = Vec::new();
        for (a, key) in FIELDS.iter().enumerate().take(d) {
            let Some(fl) = f.get(key) else {
                continue;
            };
            let Some(e) = self.expr_of(fl, "a displacement") else {
                ok = false;
                continue;
            };
            self.box_coords = true;
            let g = self.geometry(e, Dim::LENGTH, d, &format!("the field `{key}`"));
            self.box_coords = false;
            match g {
                Some(g) => {
                    morph.field[a] = Some(g);
                    morph.text.push(format!("{key} = {}", self.text(e.span)));
                    written.push((a, e.span));
                }
                None => ok = false,
            }
        }
        let (Some(b), true) = (body, ok) else {
            return;
        };
        if !self.body_spans.get(b).is_some_and(|s| s.ok) {
            return;
        }
        if written.is_empty() {
            self.error(
                Diagnostic::warning("cso::morph", format!("{label} moves nothing"))
                    .label(name.span, "no field")
                    .help(format!(
                        "give the displacement, e.g. `{}`",
                        if d == 2 {
                            "uy = bezier(c, u) * (1 - v)"
                        } else {
                            "uz = bezier2(c, u, v) * (1 - w)"
                        }
                    )),
            );
        } else if let (false, Some(first), Some(last)) =
            (morph.uses_design(), written.first(), written.last())
        {
            let span = first.1.to(last.1);
            self.error(
                Diagnostic::warning(
                    "cso::morph",
                    format!("{label} uses no design variable: a fixed deformation"),
                )
                .label(span, "the same at every design")
                .help("allowed, but the body could be meshed in that shape; drive it with a `design` to shape it"),
            );
        }
        if self.bodies[b].nodes() > NODE_CHECKS {
            // Too large to list its nodes here: the memory estimate that
            // follows judges it, and the solve checks every element.
            self.bodies[b].morphs.push(morph);
            return;
        }
        if self.box_holds_nodes(b, &morph, name.span) {
            self.shearing_faces(b, &morph, &written);
            self.bodies[b].morphs.push(morph);
            self.folds_at_start(b, name.span);
        }
    }

    /// The body's mesh at the initial design, its morphs so far applied:
    /// a node without a finite position, or an element folded over or
    /// squeezed flat, is an error on the morph that did it (the state solve
    /// would refuse that design); the body is then not checked further.
    fn folds_at_start(&mut self, b: usize, at: Span) {
        let design = self.design_init();
        let body = &self.bodies[b];
        let before = body.unmorphed_positions(&design);
        let nodes = body.positions(&design);
        let name = body.name.clone();
        let d = body.extent.len();
        let problem = if let Some(n) = nodes
            .iter()
            .position(|p| !p[..d].iter().all(|v| v.is_finite()))
        {
            let place: Vec<String> = before[n][..d].iter().map(|v| num(*v)).collect();
            Diagnostic::new(
                "cso::not-finite",
                format!("at the initial design the morph's field is not finite at a node of body `{name}`"),
            )
            .label(at, format!("not finite at ({}) m", place.join(", ")))
            .help("the field divides by zero or leaves its functions' domains there (`1 / u` at u = 0, `sqrt` of a negative value)")
        } else {
            let Err(f) = body.quality(&nodes, &before) else {
                return;
            };
            let place: Vec<String> = f.centroid.iter().map(|v| num(*v)).collect();
            let how = match f.squeezed {
                Some(r) => format!("squeezed to {} of its size", num(r)),
                None => format!("scaled Jacobian {}", num(f.scaled_jacobian)),
            };
            Diagnostic::new(
                "cso::inverted",
                format!("at the initial design the morph folds an element of body `{name}` over"),
            )
            .label(at, format!("the element at ({}) m: {how}", place.join(", ")))
            .help("a node moves past (or onto) its neighbour: make the initial displacement smaller, or the box larger so that the field varies more gently")
        };
        self.error(problem);
        if let Some(s) = self.body_spans.get_mut(b) {
            s.ok = false;
        }
    }

    /// `x = a .. b`: a box range of constant lengths, not empty.
    fn box_range(&mut self, fl: &'a crate::lang::ast::Field, key: &str) -> Option<(f64, f64)> {
        let (a, b) = self.range_of(fl)?;
        let what = format!("the box's `{key}`");
        let lo = self.number(a, Some(Dim::LENGTH), &what);
        let hi = self.number(b, Some(Dim::LENGTH), &what);
        let (lo, hi) = (lo?, hi?);
        if lo >= hi {
            self.error(
                Diagnostic::new(
                    "cso::range",
                    format!("the box's `{key} = {} .. {}` is empty", num(lo), num(hi)),
                )
                .label(a.span.to(b.span), "the start must be below the end"),
            );
            return None;
        }
        Some((lo, hi))
    }

    /// A box that holds none of the body's nodes (at the initial design,
    /// before any morph) is an error naming the body's extent.
    fn box_holds_nodes(&mut self, b: usize, morph: &Morph, at: Span) -> bool {
        let body = &self.bodies[b];
        let d = body.extent.len();
        let design = self.design_init();
        let nodes = body.unmorphed_positions(&design);
        let zero = vec![0.0; self.design_vars.len()];
        if nodes
            .iter()
            .any(|p| morph.displacement(p, d, &zero).is_some())
        {
            return true;
        }
        let (lo, hi) = bounding_box(&nodes, d);
        let spans: Vec<String> = (0..d).map(|a| extent_text(a, lo[a], hi[a])).collect();
        let boxed: Vec<String> = (0..d)
            .map(|a| extent_text(a, morph.lo[a], morph.hi[a]))
            .collect();
        let name = body.name.clone();
        self.error(
            Diagnostic::new(
                "cso::morph",
                format!("the morph's box holds no node of body `{name}`"),
            )
            .label(at, format!("the box is {}", boxed.join(", ")))
            .help(format!(
                "body `{name}` spans {}; put the box over the part to shape",
                spans.join(", ")
            )),
        );
        false
    }

    /// Each face of the box that lies inside the body's extent cuts through
    /// it: the field must vanish there, or the mesh shears along the face. A
    /// warning per face, with the largest displacement found on it at the
    /// initial design, the bounds and two mixed designs.
    fn shearing_faces(&mut self, b: usize, morph: &Morph, written: &[(usize, Span)]) {
        let (Some(first), Some(last)) = (written.first(), written.last()) else {
            return;
        };
        let span = first.1.to(last.1);
        let body = &self.bodies[b];
        let d = body.extent.len();
        let nodes = body.unmorphed_positions(&self.design_init());
        let (lo, hi) = bounding_box(&nodes, d);
        let size = (0..d).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let designs = self.sample_designs();
        let name = body.name.clone();
        let mut found = Vec::new();
        for a in 0..d {
            for (side, c) in [(0.0, morph.lo[a]), (1.0, morph.hi[a])] {
                let tol = 1e-9 * size;
                if c <= lo[a] + tol || c >= hi[a] - tol {
                    continue;
                }
                let largest = face_largest(morph, d, a, side, &designs, (&lo, &hi));
                if largest > 1e-9 * size {
                    found.push((a, side, c, largest));
                }
            }
        }
        for (a, side, c, largest) in found {
            self.error(
                Diagnostic::warning(
                    "cso::morph-shear",
                    format!(
                        "the morph's field does not vanish on the box face {} = {} ({} = {} m), which cuts through body `{name}`",
                        BOX[a],
                        side,
                        AXES[a],
                        num(c)
                    ),
                )
                .label(span, format!("moves up to {} m there", num(largest)))
                .help(format!(
                    "nodes just outside the box stay, so the elements across that face shear; \
                     make the field zero there (multiply by `{0}` or `(1 - {0})`), or extend the box past the body",
                    BOX[a]
                )),
            );
        }
    }

    /// Designs to sample a field at: the initial one, the lower and upper
    /// bounds, and the two alternations of them (a field linear in the
    /// design that is zero at all of these is zero at every design along the
    /// sampled directions that matter in practice).
    pub(super) fn sample_designs(&self) -> Vec<Vec<f64>> {
        let vars = &self.design_vars;
        let pick = |even_low: bool| -> Vec<f64> {
            vars.iter()
                .enumerate()
                .map(|(i, v)| {
                    if (i % 2 == 0) == even_low {
                        v.lower
                    } else {
                        v.upper
                    }
                })
                .collect()
        };
        vec![
            self.design_init(),
            vars.iter().map(|v| v.lower).collect(),
            vars.iter().map(|v| v.upper).collect(),
            pick(true),
            pick(false),
        ]
    }
}

/// The largest displacement of `morph` on its face `axis = side` (0 or 1 in
/// box coordinates), sampled over the part of the face inside the body's
/// bounding box `lo .. hi`, at each of `designs`.
fn face_largest(
    morph: &Morph,
    d: usize,
    axis: usize,
    side: f64,
    designs: &[Vec<f64>],
    (lo, hi): (&[f64; 3], &[f64; 3]),
) -> f64 {
    let others: Vec<usize> = (0..d).filter(|&a| a != axis).collect();
    // The face's part over the body, in box coordinates.
    let range: Vec<(f64, f64)> = others
        .iter()
        .map(|&a| {
            let w = morph.hi[a] - morph.lo[a];
            let from = ((lo[a] - morph.lo[a]) / w).clamp(0.0, 1.0);
            let to = ((hi[a] - morph.lo[a]) / w).clamp(0.0, 1.0);
            (from, to)
        })
        .collect();
    let samples = FACE_SAMPLES.pow(others.len() as u32);
    let mut largest: f64 = 0.0;
    for s in 0..samples {
        let mut at = [0.0; 3];
        at[axis] = side;
        let mut k = s;
        for (o, &a) in others.iter().enumerate() {
            let t = (k % FACE_SAMPLES) as f64 / (FACE_SAMPLES - 1) as f64;
            k /= FACE_SAMPLES;
            at[a] = range[o].0 + (range[o].1 - range[o].0) * t;
        }
        for design in designs {
            for f in morph.field.iter().flatten() {
                let v = f.eval_f64(at, design);
                largest = largest.max(if v.is_finite() { v.abs() } else { 0.0 });
            }
        }
    }
    largest
}

/// The fields of a morph in `d` dimensions.
fn morph_spec(d: usize) -> Vec<Spec> {
    let mut spec = vec![req("x", "x = 0 .. 40 mm"), req("y", "y = 0 .. 5 mm")];
    if d == 3 {
        spec.push(req("z", "z = 0 .. 5 mm"));
    }
    spec.extend([
        opt("ux", "ux = ..."),
        opt("uy", "uy = bezier2(c, u, v) * (1 - v)"),
    ]);
    if d == 3 {
        spec.push(opt("uz", "uz = ..."));
    }
    spec
}

/// Hints for fields a morph does not have.
fn morph_hint(name: &str, d: usize) -> Option<String> {
    match name {
        "z" | "uz" if d == 2 => Some(format!(
            "`{name}` is for 3D scenes; a 2D morph has the box `x`, `y` and the fields `ux`, `uy`"
        )),
        "u" | "v" | "w" | "dx" | "dy" | "dz" => Some(
            "the displacement is written `ux = ..`, `uy = ..` (and `uz` in 3D); `u`, `v`, `w` are the box's coordinates inside them"
                .to_string(),
        ),
        "body" => Some("the body is named after `morph`: `morph BODY { .. }`".to_string()),
        _ => None,
    }
}
