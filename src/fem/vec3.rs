//! Vectors of three components by value, for the facet and simplex formulas
//! (one copy for the quadrilateral face, the triangle face and the
//! tetrahedron). Sums run from the first component on, as everywhere.

use crate::num::Scalar;

/// `a x b`.
pub(super) fn cross<T: Scalar>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a . b`.
pub(super) fn dot<T: Scalar>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a - b`.
pub(super) fn sub<T: Scalar>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    std::array::from_fn(|k| a[k] - b[k])
}
