//! Mesh quality: the scaled Jacobian of an element (Knupp; the definition of
//! the Verdict library that ParaView and Cubit report).
//!
//! At each corner, the determinant of the edges that leave it (the corner's
//! Jacobian), divided by the product of their lengths, is the sine of the
//! angle in 2D and its 3D analogue: 1 for a right corner, 0 for a flat one,
//! negative for one folded over. An element's value is its worst corner's;
//! simplices are scaled so that the equilateral triangle and the regular
//! tetrahedron score 1. A morph that drives it to 0 or below has inverted an
//! element.

use super::Element;

/// The corners' edges of a hexahedron (bottom face counter-clockwise, then
/// the top): for each node, its three neighbours in right-handed order, so
/// that `det[pa - p, pb - p, pc - p] > 0` at every corner of a valid one.
pub const HEX_CORNERS: [[usize; 4]; 8] = [
    [0, 1, 3, 4],
    [1, 2, 0, 5],
    [2, 3, 1, 6],
    [3, 0, 2, 7],
    [4, 7, 5, 0],
    [5, 4, 6, 1],
    [6, 5, 7, 2],
    [7, 6, 4, 3],
];

/// The smallest scaled Jacobian of an element's corners; `x` holds the node
/// coordinates (`dim` per node). NaN for a degenerate corner (an edge of
/// length 0).
pub fn scaled_jacobian(element: Element, x: &[f64]) -> f64 {
    let p2 = |k: usize| [x[2 * k], x[2 * k + 1]];
    let p3 = |k: usize| [x[3 * k], x[3 * k + 1], x[3 * k + 2]];
    match element {
        Element::Quad4 => (0..4)
            .map(|k| corner_2d(p2(k), p2((k + 1) % 4), p2((k + 3) % 4)))
            .fold(f64::INFINITY, min_nan),
        Element::Tri3 => {
            let s = 2.0 / 3f64.sqrt();
            (0..3)
                .map(|k| s * corner_2d(p2(k), p2((k + 1) % 3), p2((k + 2) % 3)))
                .fold(f64::INFINITY, min_nan)
        }
        Element::Hex8 => HEX_CORNERS
            .iter()
            .map(|c| corner_3d(p3(c[0]), [p3(c[1]), p3(c[2]), p3(c[3])]))
            .fold(f64::INFINITY, min_nan),
        Element::Tet4 => {
            // Even permutations of (0; 1, 2, 3): the same signed volume from
            // every corner.
            let corners = [[0, 1, 2, 3], [1, 2, 0, 3], [2, 0, 1, 3], [3, 0, 2, 1]];
            corners
                .iter()
                .map(|c| 2f64.sqrt() * corner_3d(p3(c[0]), [p3(c[1]), p3(c[2]), p3(c[3])]))
                .fold(f64::INFINITY, min_nan)
        }
    }
}

/// An element folded over, flat, or squeezed to almost nothing: where it is
/// and how badly.
#[derive(Debug, Clone, PartialEq)]
pub struct Folded {
    /// The element's centroid, one value per axis.
    pub centroid: Vec<f64>,
    pub scaled_jacobian: f64,
    /// Its area (volume) over its area before the morphs, where that is below
    /// [`SQUEEZED`] (its corners may still be square).
    pub squeezed: Option<f64>,
}

/// An element whose area (volume) falls below this share of what it was
/// before the morphs counts as collapsed: the scaled Jacobian measures
/// corners, so an element pressed flat between square corners still scores
/// well, while its stiffness degenerates.
pub const SQUEEZED: f64 = 1e-3;

/// The smallest scaled Jacobian of a mesh's elements (`cells`, node indices
/// into `nodes`, each `element`), or the first element at 0 or below, or (with
/// the node positions before the morphs, `before`) squeezed below
/// [`SQUEEZED`] of its size.
pub fn worst<'a>(
    element: Element,
    cells: impl Iterator<Item = &'a [usize]>,
    nodes: &[[f64; 3]],
    before: Option<&[[f64; 3]]>,
) -> Result<f64, Folded> {
    let dim = element.dim();
    let mut smallest = f64::INFINITY;
    let mut x = Vec::with_capacity(dim * element.nodes());
    let mut x0 = Vec::with_capacity(dim * element.nodes());
    for cell in cells {
        x.clear();
        x.extend(cell.iter().flat_map(|&n| nodes[n][..dim].iter().copied()));
        let q = scaled_jacobian(element, &x);
        let squeezed = before.and_then(|b| {
            x0.clear();
            x0.extend(cell.iter().flat_map(|&n| b[n][..dim].iter().copied()));
            let (now, was) = (element.measure(&x)?, element.measure(&x0)?);
            let ratio = now / was;
            (ratio < SQUEEZED).then_some(ratio)
        });
        if q.is_nan() || q <= 0.0 || squeezed.is_some() {
            let centroid = (0..dim)
                .map(|a| cell.iter().map(|&n| nodes[n][a]).sum::<f64>() / cell.len() as f64)
                .collect();
            return Err(Folded {
                centroid,
                scaled_jacobian: q,
                squeezed,
            });
        }
        smallest = smallest.min(q);
    }
    Ok(smallest)
}

/// The smaller of two values, NaN if either is.
fn min_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.min(b)
    }
}

/// `det[a - o, b - o] / (|a - o| |b - o|)`.
fn corner_2d(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (e, f) = ([a[0] - o[0], a[1] - o[1]], [b[0] - o[0], b[1] - o[1]]);
    let det = e[0] * f[1] - e[1] * f[0];
    let lengths = e[0].hypot(e[1]) * f[0].hypot(f[1]);
    if lengths > 0.0 {
        det / lengths
    } else {
        f64::NAN
    }
}

/// `det[a - o, b - o, c - o] / (|a - o| |b - o| |c - o|)`.
fn corner_3d(o: [f64; 3], n: [[f64; 3]; 3]) -> f64 {
    let e: [[f64; 3]; 3] = n.map(|p| [p[0] - o[0], p[1] - o[1], p[2] - o[2]]);
    let det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1])
        - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
        + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    let lengths: f64 = e
        .iter()
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .product();
    if lengths > 0.0 {
        det / lengths
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }

    #[test]
    fn ideal_elements_score_one() {
        close(
            scaled_jacobian(Element::Quad4, &[0., 0., 2., 0., 2., 2., 0., 2.]),
            1.0,
        );
        let h = 3f64.sqrt() / 2.0;
        close(
            scaled_jacobian(Element::Tri3, &[0., 0., 1., 0., 0.5, h]),
            1.0,
        );
        let cube = [
            0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0., 0., 0., 1., 1., 0., 1., 1., 1., 1., 0.,
            1., 1.,
        ];
        close(scaled_jacobian(Element::Hex8, &cube), 1.0);
        // The regular tetrahedron: alternate corners of a cube, listed with
        // a positive volume (as the importer keeps them).
        let tet = [0., 0., 0., 1., 0., 1., 1., 1., 0., 0., 1., 1.];
        assert!(Element::Tet4.measure(&tet).is_some_and(|v| v > 0.0));
        close(scaled_jacobian(Element::Tet4, &tet), 1.0);
        // Two nodes swapped: the same tetrahedron inside out.
        let swapped = [0., 0., 0., 1., 1., 0., 1., 0., 1., 0., 1., 1.];
        close(scaled_jacobian(Element::Tet4, &swapped), -1.0);
    }

    #[test]
    fn a_sheared_quad_scores_the_sine_of_its_angle_and_a_folded_one_is_negative() {
        // A parallelogram with 60 degree corners: sin 60 at every corner.
        let c = 0.5;
        let s = 3f64.sqrt() / 2.0;
        let q = [0., 0., 1., 0., 1. + c, s, c, s];
        close(scaled_jacobian(Element::Quad4, &q), s);
        // Node 2 pulled through the diagonal: the quadrilateral folds over.
        let folded = [0., 0., 1., 0., 0.2, 0.2, 0., 1.];
        assert!(scaled_jacobian(Element::Quad4, &folded) < 0.0);
        // A triangle listed clockwise is inverted.
        assert!(scaled_jacobian(Element::Tri3, &[0., 0., 0., 1., 1., 0.]) < 0.0);
        // A flattened hexahedron: its top on its bottom scores 0.
        let flat = [
            0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 1., 1., 0., 0.,
            1., 0.,
        ];
        assert!(scaled_jacobian(Element::Hex8, &flat).is_nan());
        let squashed = [
            0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0., 0., 0., -0.1, 1., 0., -0.1, 1., 1.,
            -0.1, 0., 1., -0.1,
        ];
        assert!(scaled_jacobian(Element::Hex8, &squashed) < 0.0);
    }
}
