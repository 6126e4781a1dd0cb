//! Objectives and constraints that cannot change: found before anything is solved.
//!
//! Two things make a functional constant on a scene, and both are decided from the
//! scene alone:
//!
//! * the loads: `compliance` (f·u) is 0 when nothing applies a force (no `traction`,
//!   `pressure` or `gravity`), whatever the prescribed displacements; every
//!   functional of the solution (energy, contact forces, pressures, probes) is 0
//!   when there is no force and no nonzero `displace` either (the bodies stay at
//!   rest);
//! * the design: `area(b)` / `volume(b)` of a body whose geometry uses no design
//!   variable, a formula without design variables, `initial(...)`, and every
//!   functional of the solution when no body, obstacle or selection moves with the
//!   design.
//!
//! The rule (docs/language.md, "Constant objectives and constraints"): an objective
//! that is identically 0, or that the design cannot change when the scene has
//! design variables, is an error (optimizing it is meaningless: the optimizer would
//! stop at once). A constraint whose two sides are known numbers is an error when it
//! can never hold and a warning when it always holds; one that is constant with a
//! value known only after a solve is a warning. A term of an objective or
//! constraint that is identically 0 while the rest changes is a warning.

use super::Checker;
use crate::lang::ast::{BinOp, Expr, ExprKind, ItemKind, Span, UnOp};
use crate::lang::diag::{num, Diagnostic};
use crate::lang::expr::{Arith, Formula, Func};
use crate::lang::functional::Operand;
use crate::lang::scene::{Condition, Functional, Leaf, Obstacle, Scene};

/// What a functional does as the design changes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Dep {
    /// The same value at every design: known (`Some`) or known only after a solve.
    Const(Option<f64>),
    Varies,
}

const ZERO: Dep = Dep::Const(Some(0.0));

/// Why a part of a functional is constant, and where it is written.
#[derive(Debug, Clone, Copy)]
struct Part {
    span: Span,
    why: Why,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Why {
    /// `compliance` with no applied force.
    NoForce,
    /// A functional of the solution with no force and no prescribed displacement.
    Unloaded,
    /// `area`/`volume` of a body whose geometry uses no design variable.
    FixedBody(usize),
    /// A functional of the solution when nothing moves with the design.
    NothingMoves,
    /// `initial(...)`.
    Initial,
}

impl Why {
    fn zero(self) -> bool {
        matches!(self, Why::NoForce | Why::Unloaded)
    }
}

/// What loads the scene, and what moves with the design.
struct Facts {
    force: bool,
    displacement: bool,
    moves: bool,
    fixed_body: Vec<bool>,
    design: Vec<f64>,
}

impl Facts {
    fn of(scene: &Scene) -> Facts {
        let mut force = scene
            .gravity
            .as_ref()
            .is_some_and(|g| g.iter().any(|c| *c != 0.0));
        let mut displacement = false;
        let mut filters = false;
        for c in &scene.conditions {
            filters |= c
                .selection()
                .filter
                .as_ref()
                .is_some_and(|f| f.uses_design());
            match c {
                Condition::Traction { value, .. } => force |= value.iter().any(|v| *v != 0.0),
                Condition::Pressure { value, .. } => force |= *value != 0.0,
                Condition::Displace { values, .. } => {
                    displacement |= values.iter().any(|(_, v)| *v != 0.0)
                }
                Condition::Fix { .. } | Condition::Symmetry { .. } => {}
            }
        }
        let selections = scene
            .contacts
            .iter()
            .map(|c| &c.secondary)
            .chain(scene.contacts.iter().filter_map(|c| match &c.primary {
                crate::lang::scene::Primary::Face(s) => Some(s),
                crate::lang::scene::Primary::Obstacle(_) => None,
            }))
            .chain(scene.glues.iter().flat_map(|g| [&g.primary, &g.secondary]));
        for s in selections {
            filters |= s.filter.as_ref().is_some_and(|f| f.uses_design());
        }
        let fixed_body: Vec<bool> = scene.bodies.iter().map(|b| !b.uses_design()).collect();
        let obstacle_moves = scene.obstacles.iter().any(|o| match o {
            Obstacle::Plane { point, normal, .. } => {
                point.iter().chain(normal).any(Formula::uses_design)
            }
            Obstacle::Sphere { center, radius, .. } => {
                radius.uses_design() || center.iter().any(Formula::uses_design)
            }
        });
        Facts {
            force,
            displacement,
            moves: !scene.design.is_empty()
                && (fixed_body.iter().any(|f| !f) || obstacle_moves || filters),
            fixed_body,
            design: scene.design_init(),
        }
    }

    /// A functional of the solution other than compliance.
    fn state(&self, span: Span, parts: &mut Vec<Part>) -> Dep {
        if !self.force && !self.displacement {
            parts.push(Part {
                span,
                why: Why::Unloaded,
            });
            ZERO
        } else if !self.moves {
            parts.push(Part {
                span,
                why: Why::NothingMoves,
            });
            Dep::Const(None)
        } else {
            Dep::Varies
        }
    }

    /// How `f` (written as `e`) depends on the design; constant parts go to `parts`.
    fn dep(&self, f: &Functional, e: &Expr, parts: &mut Vec<Part>) -> Dep {
        f.eval_at(e, &child, &mut |l, e| self.leaf(l, e.span, parts))
    }

    /// How a leaf (written at `span`) depends on the design.
    fn leaf(&self, l: &Leaf, span: Span, parts: &mut Vec<Part>) -> Dep {
        match l {
            Leaf::Geometry(g) if g.uses_design() => Dep::Varies,
            Leaf::Geometry(g) => Dep::Const(Some(g.eval_f64([0.0; 3], &self.design))),
            Leaf::Compliance if !self.force => {
                parts.push(Part {
                    span,
                    why: Why::NoForce,
                });
                ZERO
            }
            Leaf::Compliance
            | Leaf::Energy
            | Leaf::ContactForce(_)
            | Leaf::PressureNorm(..)
            | Leaf::Probe(..) => self.state(span, parts),
            Leaf::Area(b) | Leaf::Volume(b) => {
                if self.fixed_body.get(*b).copied().unwrap_or(false) {
                    parts.push(Part {
                        span,
                        why: Why::FixedBody(*b),
                    });
                    Dep::Const(None)
                } else {
                    Dep::Varies
                }
            }
            Leaf::Initial(_) => {
                parts.push(Part {
                    span,
                    why: Why::Initial,
                });
                Dep::Const(None)
            }
        }
    }
}

impl Dep {
    fn map(self, f: impl FnOnce(f64) -> f64) -> Dep {
        match self {
            Dep::Const(v) => Dep::Const(v.map(f)),
            Dep::Varies => Dep::Varies,
        }
    }
}

/// Constant folding is the functional's own arithmetic on known constants. A
/// product with a factor that is 0, and a quotient of 0, are 0 whatever the
/// other operand does; otherwise anything that varies makes the result vary.
impl Operand for Dep {
    fn negate(self) -> Dep {
        self.map(|v| v.negate())
    }
    fn arith(op: Arith, a: Dep, b: Dep) -> Dep {
        match (op, a, b) {
            (Arith::Mul, ZERO, _) | (Arith::Mul, _, ZERO) | (Arith::Div, ZERO, _) => ZERO,
            (_, Dep::Varies, _) | (_, _, Dep::Varies) => Dep::Varies,
            (op, Dep::Const(a), Dep::Const(b)) => {
                Dep::Const(a.zip(b).map(|(a, b)| f64::arith(op, a, b)))
            }
        }
    }
    fn power(self, p: f64) -> Dep {
        self.map(|v| v.power(p))
    }
    fn function(self, f: Func) -> Dep {
        self.map(|v| v.function(f))
    }
}

/// The `i`-th operand of an expression as the functional checker reads it (the
/// expression itself when its shape is not one it knows).
fn child(e: &Expr, i: usize) -> &Expr {
    match &e.kind {
        ExprKind::Unary(UnOp::Neg, a) if i == 0 => a,
        ExprKind::Binary(BinOp::Pow, a, _) if i == 0 => a,
        ExprKind::Binary(_, a, b) => {
            if i == 0 {
                a
            } else {
                b
            }
        }
        ExprKind::Call { args, .. } => args.get(i).unwrap_or(e),
        _ => e,
    }
}

impl Checker<'_> {
    /// Names objectives and constraints that are constant on the scene (see the
    /// module's rule).
    pub(crate) fn constant_functionals(&mut self, scene: &Scene) {
        let facts = Facts::of(scene);
        let has_design = !scene.design.is_empty();
        if let (Some(obj), Some(at)) = (&scene.objective, self.objective_at) {
            let e = self.find_expr(at, true);
            let mut parts = Vec::new();
            let dep = e.map_or(Dep::Varies, |e| facts.dep(&obj.functional, e, &mut parts));
            match dep {
                ZERO => self.objective_zero(scene, at, &parts, &facts),
                Dep::Const(_) if has_design => self.objective_fixed(scene, at, &parts),
                _ => self.zero_terms(scene, "objective", &parts, &facts),
            }
        }
        for (c, &at) in scene.constraints.iter().zip(&self.constraint_at.clone()) {
            let Some(e) = self.find_expr(at, false) else {
                continue;
            };
            let mut parts = Vec::new();
            let l = facts.dep(&c.lhs, child(e, 0), &mut parts);
            let r = facts.dep(&c.rhs, child(e, 1), &mut parts);
            let zero = parts.iter().any(|l| l.why.zero());
            match (l, r) {
                (Dep::Const(Some(a)), Dep::Const(Some(b))) if has_design || zero => {
                    let holds = if c.upper { a <= b } else { a >= b };
                    self.constraint_decided(scene, c, at, (a, b), holds, &parts, &facts);
                }
                (Dep::Const(_), Dep::Const(_)) if has_design => {
                    let mut d = Diagnostic::warning(
                        "cso::constant-constraint",
                        "this constraint does not change with the design",
                    );
                    if parts.is_empty() {
                        d = d.label(at, "the same at every design");
                    }
                    for l in &parts {
                        d = d.label(l.span, self.why_text(scene, l.why));
                    }
                    self.error(d.help(format!(
                        "{}: the optimizer cannot move this constraint, so it always holds or \
                         never; delete it, or constrain something the design changes",
                        self.design_help()
                    )));
                }
                _ => self.zero_terms(scene, "constraint", &parts, &facts),
            }
        }
    }

    /// The checked objective's or constraint's expression at `at`.
    fn find_expr(&self, at: Span, objective: bool) -> Option<&Expr> {
        self.file.items.iter().find_map(|i| match &i.kind {
            ItemKind::Minimize { expr } if objective && expr.span == at => Some(expr),
            ItemKind::SubjectTo { expr } if !objective && expr.span == at => Some(expr),
            _ => None,
        })
    }

    fn why_text(&self, scene: &Scene, why: Why) -> String {
        match why {
            Why::NoForce => "always 0: no force loads this scene".into(),
            Why::Unloaded => "always 0: nothing loads this scene".into(),
            Why::FixedBody(b) => {
                let name = scene.bodies.get(b).map_or("", |b| b.name.as_str());
                format!("the geometry of `{name}` uses no design variable")
            }
            Why::NothingMoves => "no body or obstacle moves with the design".into(),
            Why::Initial => "a number: the value at the initial design".into(),
        }
    }

    /// "the design variables `h`, `a[6]` ..." for a help text.
    fn design_help(&self) -> String {
        let names: Vec<String> = self
            .designs
            .iter()
            .map(|g| match g.size {
                Some(n) => format!("`{}[{n}]`", g.name),
                None => format!("`{}`", g.name),
            })
            .collect();
        match names.len() {
            0 => "the scene has no design variables".into(),
            1 => format!(
                "the design variable {} moves nothing this measures",
                names[0]
            ),
            _ => format!(
                "the design variables {} move nothing this measures",
                names.join(", ")
            ),
        }
    }

    /// Where the prescribed displacements are written (for compliance's help).
    fn displace_spans(&self) -> Vec<Span> {
        self.file
            .items
            .iter()
            .filter_map(|i| match &i.kind {
                ItemKind::Condition { keyword, .. } if keyword.name == "displace" => {
                    Some(keyword.span)
                }
                _ => None,
            })
            .collect()
    }

    /// The help for a part that is 0 because of the loads.
    fn zero_help(&self, parts: &[Part], facts: &Facts) -> String {
        if parts.iter().any(|l| l.why == Why::NoForce) && facts.displacement {
            "`compliance` is the work of the applied forces (f·u), and prescribed \
             displacements apply none; under prescribed displacements use the strain \
             energy: `minimize -energy` makes the structure stiffer, `minimize energy` \
             softer; or add the load the structure carries (`traction`, `pressure`, \
             `gravity`)"
                .into()
        } else {
            "nothing loads this scene (no `traction`, `pressure`, `gravity` or nonzero \
             `displace`), so every displacement, contact force and energy is 0; add the \
             load the structure carries"
                .into()
        }
    }

    fn with_zero_labels(&self, mut d: Diagnostic, parts: &[Part], facts: &Facts) -> Diagnostic {
        if parts.iter().any(|l| l.why == Why::NoForce) && facts.displacement {
            if let Some(s) = self.displace_spans().first() {
                d = d.label(
                    *s,
                    "a prescribed displacement: it does no work in `compliance`",
                );
            }
        }
        d
    }

    fn objective_zero(&mut self, scene: &Scene, at: Span, parts: &[Part], facts: &Facts) {
        let mut d = Diagnostic::new(
            "cso::constant-objective",
            "the objective is identically 0 on this scene",
        );
        let zeros: Vec<&Part> = parts.iter().filter(|l| l.why.zero()).collect();
        if zeros.is_empty() {
            d = d.label(at, "this is 0 at every design");
        }
        for l in zeros {
            d = d.label(l.span, self.why_text(scene, l.why));
        }
        d = self.with_zero_labels(d, parts, facts);
        let help = self.zero_help(parts, facts);
        self.error(d.help(help));
    }

    fn objective_fixed(&mut self, scene: &Scene, at: Span, parts: &[Part]) {
        let mut d = Diagnostic::new(
            "cso::constant-objective",
            "the objective does not change with the design",
        );
        if parts.is_empty() {
            d = d.label(at, "a number: the same at every design");
        }
        for l in parts {
            d = d.label(l.span, self.why_text(scene, l.why));
        }
        let example = self
            .designs
            .first()
            .map_or("h".to_string(), |g| match g.size {
                Some(_) => format!("{}[0]", g.name),
                None => g.name.clone(),
            });
        let help = format!(
            "{}; use the design in the geometry of what the objective measures \
             (e.g. `bottom = 1 + {example}`), or minimize something it changes",
            self.design_help()
        );
        self.error(d.help(help));
    }

    #[allow(clippy::too_many_arguments)]
    fn constraint_decided(
        &mut self,
        scene: &Scene,
        c: &crate::lang::scene::Constraint,
        at: Span,
        (a, b): (f64, f64),
        holds: bool,
        parts: &[Part],
        facts: &Facts,
    ) {
        let reads = format!(
            "{} {} {} at every design",
            num(a),
            if c.upper { "<=" } else { ">=" },
            num(b)
        );
        let mut d = if holds {
            Diagnostic::warning(
                "cso::constant-constraint",
                format!("this constraint always holds: it reads {reads}"),
            )
        } else {
            Diagnostic::new(
                "cso::constant-constraint",
                format!("this constraint can never hold: it reads {reads}"),
            )
        };
        if parts.is_empty() {
            d = d.label(at, "the same at every design");
        }
        for l in parts {
            d = d.label(l.span, self.why_text(scene, l.why));
        }
        d = self.with_zero_labels(d, parts, facts);
        let help = if parts.iter().any(|l| l.why.zero()) {
            self.zero_help(parts, facts)
        } else if holds {
            "it constrains nothing: delete it".into()
        } else {
            "no design satisfies it: fix the bound or delete the constraint".into()
        };
        self.error(d.help(help));
    }

    /// A warning for the parts of a changing objective or constraint that are 0.
    fn zero_terms(&mut self, scene: &Scene, what: &str, parts: &[Part], facts: &Facts) {
        let zeros: Vec<&Part> = parts.iter().filter(|l| l.why.zero()).collect();
        if zeros.is_empty() {
            return;
        }
        let mut d = Diagnostic::warning(
            "cso::zero-term",
            format!("a term of this {what} is identically 0 on this scene"),
        );
        for l in zeros {
            d = d.label(l.span, self.why_text(scene, l.why));
        }
        d = self.with_zero_labels(d, parts, facts);
        let help = self.zero_help(parts, facts);
        self.error(d.help(help));
    }
}
