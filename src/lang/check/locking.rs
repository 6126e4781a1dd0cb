//! Volumetric locking: a nearly incompressible material on an element that
//! integrates its volumetric strain in full is far too stiff, silently. The
//! elements choose B-bar for it (`material { formulation }`); where a body
//! still gets the standard element (asked for, or an element without B-bar),
//! the checker warns.

use super::BodySpans;
use crate::fem::{Element, Formulation, NEARLY_INCOMPRESSIBLE};
use crate::lang::ast::Span;
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::{Material, Scene};

/// One warning per body whose material is nearly incompressible and whose
/// elements lock.
pub(super) fn warnings(scene: &Scene, spans: &[BodySpans]) -> Vec<Diagnostic> {
    scene
        .bodies
        .iter()
        .zip(spans)
        .filter_map(|(body, spans)| {
            let element: Element = body.element(scene.dim.n());
            let material = scene.materials.get(body.material)?;
            let used = material.section(element, scene.thickness).formulation;
            if material.poisson < NEARLY_INCOMPRESSIBLE || used == Formulation::Bbar {
                return None;
            }
            let has_bbar = element.has_bbar();
            Some(warning(
                &body.name,
                material,
                element.name(),
                has_bbar,
                spans.name,
            ))
        })
        .collect()
}

/// The warning for body `body` of `material` on `element` (in words), which
/// has B-bar or not.
fn warning(body: &str, material: &Material, element: &str, has_bbar: bool, at: Span) -> Diagnostic {
    let nu = num(material.poisson);
    let (why, help) = if has_bbar {
        (
            format!("`formulation = standard` locks at nu = {nu}"),
            format!(
                "remove `formulation = standard` from material `{}`: from nu = {} on \
                 the elements are B-bar (mean dilatation), which does not lock",
                material.name,
                num(NEARLY_INCOMPRESSIBLE)
            ),
        )
    } else {
        (
            format!("{element} has no locking-free formulation for nu = {nu}"),
            "refine until the displacements stop growing, or mesh with elements that have B-bar"
                .to_string(),
        )
    };
    Diagnostic::warning(
        "cso::locking",
        format!(
            "body `{body}` is nearly incompressible (material `{}`, nu = {nu}) and its \
             elements lock: displacements come out too small",
            material.name
        ),
    )
    .label(at, why)
    .help(help)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lang::scene::Formulation as Written;

    /// An element without B-bar (a linear triangle, say) warns whatever the
    /// material asks for.
    #[test]
    fn an_element_without_bbar_warns_with_its_own_words() {
        let m = Material {
            name: "rubber".into(),
            young: 1e6,
            poisson: 0.4999,
            density: None,
            formulation: Written::Auto,
        };
        let d = warning("seal", &m, "the linear triangle", false, Span::new(0, 4));
        assert!(!d.is_error());
        let text = format!("{} | {:?}", d.message, d.labels);
        assert!(
            text.contains("body `seal` is nearly incompressible")
                && text.contains("the linear triangle has no locking-free formulation"),
            "{text}"
        );
    }
}
