//! The element types a subdomain is assembled from, behind one interface: the
//! solver asks an [`Element`] for its size and its stiffness, never whether the
//! scene is 2D or 3D. Adding the trilinear hexahedron adds a variant here (and
//! its routine beside [`super::quad`]); nothing in `tfeti/` changes, as the
//! hexahedron showed. The linear triangle and tetrahedron (from a mesher's
//! files) are two more: their strain is constant, so B-bar is the standard
//! element on them and they lock near incompressibility
//! ([`Element::locks_near_incompressible`]).

use super::hex::{hex_dilatation, hex_gradients, hex_stiffness, isotropic, isotropic_deviatoric};
use super::hex::{hex_gauss, hex_strain_at};
use super::quad::{
    plane_strain, plane_strain_deviatoric, quad_dilatation, quad_gradients, quad_stiffness,
};
use super::quad::{quad_gauss, quad_strain_at};
use super::shape_gradient::{bilinear_shape_gradient, mean_dilatation_shape_gradient};
use super::tet::{tet_gauss, tet_gradients, tet_stiffness, tet_strain};
use super::tri::{tri_gauss, tri_gradients, tri_stiffness, tri_strain};
use crate::num::Scalar;

/// An element type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Element {
    /// Bilinear quadrilateral, plane strain (2D, 4 nodes).
    Quad4,
    /// Trilinear hexahedron (3D, 8 nodes).
    Hex8,
    /// Linear triangle, plane strain (2D, 3 nodes, counter-clockwise).
    Tri3,
    /// Linear tetrahedron (3D, 4 nodes, positive volume).
    Tet4,
}

/// Poisson's ratio from which [`Element::formulation`] chooses B-bar unless
/// told otherwise. The standard Q1's volumetric locking grows as `lambda / mu
/// = 2 nu / (1 - 2 nu)` (1.5 at 0.3, 9 at 0.45, 4999 at 0.4999): on Lamé's
/// cylinder (4 x 8 elements, `fem::tests`) its largest error is 1.3 % at
/// 0.3, 2.1 % at 0.4, 3.6 % at 0.45, 14 % at 0.49 and 94 % at 0.4999, B-bar's
/// 0.7 % throughout. From 0.45 on the standard element is five times worse
/// and soon useless; below, it is within a discretization error and kept, so
/// existing answers do not change. No common metal reaches 0.45 (lead and
/// gold, the highest, are about 0.44): it switches rubber-like materials.
pub const NEARLY_INCOMPRESSIBLE: f64 = 0.45;

/// How an element integrates the volumetric strain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Formulation {
    /// Every strain component at every Gauss point: locks as `nu -> 0.5`.
    Standard,
    /// B-bar (Hughes 1980), mean dilatation: the volumetric strain replaced by
    /// its element mean, the deviatoric strain kept at the Gauss points. The
    /// stiffness is `K_dev + kappa c c^T / V` (`c = int div N`, [`quad_dilatation`]):
    /// symmetric, semidefinite, the same rigid modes, no locking.
    Bbar,
}

/// What an element's stiffness needs besides its nodes (what Abaqus calls a
/// section): the isotropic material, the thickness (2D, plane strain per unit
/// of it; 1 in 3D) and the formulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    pub young: f64,
    pub poisson: f64,
    pub thickness: f64,
    pub formulation: Formulation,
}

impl Section {
    /// The bulk modulus `kappa = E / (3 (1 - 2 nu))`.
    pub fn bulk_modulus(&self) -> f64 {
        self.young / (3.0 * (1.0 - 2.0 * self.poisson))
    }
}

impl Element {
    /// The element of a structured body (a grid of bricks) in `dim`
    /// dimensions (2: quadrilaterals, else hexahedra); a body from a mesh file
    /// names its own.
    pub fn for_dim(dim: usize) -> Element {
        if dim == 2 {
            Element::Quad4
        } else {
            Element::Hex8
        }
    }

    /// Coordinates (and displacement components) per node.
    pub fn dim(self) -> usize {
        match self {
            Element::Quad4 | Element::Tri3 => 2,
            Element::Hex8 | Element::Tet4 => 3,
        }
    }

    /// Nodes per element.
    pub fn nodes(self) -> usize {
        match self {
            Element::Quad4 => 4,
            Element::Hex8 => 8,
            Element::Tri3 => 3,
            Element::Tet4 => 4,
        }
    }

    /// Dofs per element, `nodes * dim`: the side of [`Element::stiffness`].
    pub fn dofs(self) -> usize {
        self.nodes() * self.dim()
    }

    /// Whether the element is a linear simplex (constant strain).
    pub fn is_simplex(self) -> bool {
        match self {
            Element::Quad4 | Element::Hex8 => false,
            Element::Tri3 | Element::Tet4 => true,
        }
    }

    /// The element's facets (its edges in 2D, its faces in 3D) as local node
    /// indices, each ordered so that the facet with
    /// [`super::Orientation::CounterClockwise`] has its normal pointing out
    /// of the element: edges counter-clockwise around it, faces
    /// counter-clockwise seen from outside. A body's boundary is made of the
    /// facets that only one of its elements has.
    pub fn facets(self) -> &'static [&'static [usize]] {
        match self {
            Element::Quad4 => &[&[0, 1], &[1, 2], &[2, 3], &[3, 0]],
            Element::Tri3 => &[&[0, 1], &[1, 2], &[2, 0]],
            Element::Hex8 => &[
                &[0, 3, 2, 1],
                &[4, 5, 6, 7],
                &[0, 1, 5, 4],
                &[1, 2, 6, 5],
                &[2, 3, 7, 6],
                &[3, 0, 4, 7],
            ],
            Element::Tet4 => &[&[0, 2, 1], &[0, 1, 3], &[1, 2, 3], &[0, 3, 2]],
        }
    }

    /// Rigid motions of a free body in this element's dimension (3 in 2D, 6 in 3D).
    pub fn rigid_modes(self) -> usize {
        rigid_modes(self.dim())
    }

    /// In words, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Element::Quad4 => "the bilinear quadrilateral (Q1)",
            Element::Hex8 => "the trilinear hexahedron (Q1)",
            Element::Tri3 => "the linear triangle (P1)",
            Element::Tet4 => "the linear tetrahedron (P1)",
        }
    }

    /// Whether this element has a formulation that does not lock near
    /// incompressibility (B-bar): the bilinear and trilinear bricks. On a
    /// linear triangle or tetrahedron the strain is constant, so its mean
    /// dilatation is its dilatation and B-bar is the standard element: none.
    pub fn has_bbar(self) -> bool {
        match self {
            Element::Quad4 | Element::Hex8 => true,
            Element::Tri3 | Element::Tet4 => false,
        }
    }

    /// Whether this element locks (comes out far too stiff) as `nu -> 0.5`
    /// whatever the material asks: the linear triangle and tetrahedron. Each
    /// element's one constant dilatation must vanish, a constraint per
    /// element, and a mesh of them has about as many elements as dofs in 2D
    /// (two triangles and two dofs per node) and twice as many in 3D (five to
    /// six tetrahedra, three dofs per node): too few motions are left. The
    /// checker warns for a body of them from [`NEARLY_INCOMPRESSIBLE`] on;
    /// the bricks switch to B-bar there instead.
    pub fn locks_near_incompressible(self) -> bool {
        !self.has_bbar()
    }

    /// The formulation used for a material of Poisson's ratio `poisson`:
    /// `asked`, or where None (automatic) B-bar from [`NEARLY_INCOMPRESSIBLE`]
    /// on; never B-bar where the element has none (the simplices: Standard,
    /// always).
    pub fn formulation(self, poisson: f64, asked: Option<Formulation>) -> Formulation {
        let bbar = match asked {
            Some(f) => f == Formulation::Bbar,
            None => poisson >= NEARLY_INCOMPRESSIBLE,
        };
        if bbar && self.has_bbar() {
            Formulation::Bbar
        } else {
            Formulation::Standard
        }
    }

    /// The element stiffness, dense row-major `(nodes * dim)^2`, dofs
    /// interleaved per node; `x` holds the node coordinates (`dim` per node).
    /// None for an inverted or degenerate element. A simplex ignores the
    /// section's formulation: B-bar is its standard stiffness.
    pub fn stiffness<T: Scalar>(self, x: &[T], section: &Section) -> Option<Vec<T>> {
        let (young, poisson, t) = (section.young, section.poisson, section.thickness);
        let bbar = section.formulation == Formulation::Bbar;
        match self {
            Element::Quad4 => {
                let q = std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]);
                let d = if bbar {
                    plane_strain_deviatoric(young, poisson)
                } else {
                    plane_strain(young, poisson)
                };
                let mut k: Vec<T> = quad_stiffness(&q, &d, t)?
                    .iter()
                    .flatten()
                    .copied()
                    .collect();
                if bbar {
                    let (c, area) = quad_dilatation(&q)?;
                    add_mean_dilatation(&mut k, &c, area, section.bulk_modulus() * t);
                }
                Some(k)
            }
            Element::Hex8 => {
                let h = std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]);
                if !bbar {
                    return hex_stiffness(&h, &isotropic(young, poisson));
                }
                let mut k = hex_stiffness(&h, &isotropic_deviatoric(young, poisson))?;
                let (c, volume) = hex_dilatation(&h)?;
                add_mean_dilatation(&mut k, &c, volume, section.bulk_modulus());
                Some(k)
            }
            Element::Tri3 => {
                let tri = std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]);
                let k = tri_stiffness(&tri, &plane_strain(young, poisson), t)?;
                Some(k.iter().flatten().copied().collect())
            }
            Element::Tet4 => {
                let tet = std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]);
                tet_stiffness(&tet, &isotropic(young, poisson))
            }
        }
    }

    /// The element's mean dilatation `c . u / V` (B-bar's volumetric strain,
    /// [`quad_dilatation`]) at displacements `u`. None for an inverted or
    /// degenerate element.
    pub fn mean_dilatation(self, x: &[f64], u: &[f64]) -> Option<f64> {
        let (c, volume) = match self {
            Element::Quad4 => {
                let q = std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]);
                let (c, area) = quad_dilatation(&q)?;
                (c.to_vec(), area)
            }
            Element::Hex8 => hex_dilatation(&std::array::from_fn(|k| {
                [x[3 * k], x[3 * k + 1], x[3 * k + 2]]
            }))?,
            // Constant strain: the mean dilatation is the dilatation.
            Element::Tri3 => {
                let (g, area) = tri_gradients(&std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]))?;
                (g.iter().flatten().map(|v| v * area).collect(), area)
            }
            Element::Tet4 => {
                let (g, volume) = tet_gradients(&std::array::from_fn(|k| {
                    [x[3 * k], x[3 * k + 1], x[3 * k + 2]]
                }))?;
                (g.iter().flatten().map(|v| v * volume).collect(), volume)
            }
        };
        Some(c.iter().zip(u).map(|(a, b)| a * b).sum::<f64>() / volume)
    }

    /// `d(w^T K_e u) / dX` for every node coordinate (node-major, like `x`) and
    /// every `w` of `ws`, in one pass ([`super::shape_gradient`]); `w` and `u`
    /// are element vectors. None for an inverted or degenerate element. A
    /// simplex ignores B-bar, as [`Element::stiffness`] does.
    pub fn shape_gradient(
        self,
        x: &[f64],
        section: &Section,
        ws: &[&[f64]],
        u: &[f64],
    ) -> Option<Vec<Vec<f64>>> {
        let (young, poisson) = (section.young, section.poisson);
        // B-bar: the deviatoric form at the Gauss points, and the mean
        // dilatation's term with the bulk modulus.
        let kappa = (section.formulation == Formulation::Bbar).then(|| section.bulk_modulus());
        match self {
            Element::Quad4 => {
                let q = std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]);
                let points: Vec<_> = quad_gradients(&q)
                    .into_iter()
                    .map(|(g, det)| (g, det * section.thickness))
                    .collect();
                let d = match kappa {
                    Some(_) => plane_strain_deviatoric(young, poisson),
                    None => plane_strain(young, poisson),
                };
                let rows: Vec<&[f64]> = d.iter().map(|r| r.as_slice()).collect();
                gauss_shape_gradient(&points, &rows, kappa, ws, u)
            }
            Element::Hex8 => {
                let h = std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]);
                let d = match kappa {
                    Some(_) => isotropic_deviatoric(young, poisson),
                    None => isotropic(young, poisson),
                };
                let rows: Vec<&[f64]> = d.iter().map(|r| r.as_slice()).collect();
                gauss_shape_gradient(&hex_gradients(&h), &rows, kappa, ws, u)
            }
            // One point, the centroid, weighted by the measure (times the
            // thickness in 2D): exact for a constant strain.
            Element::Tri3 => {
                let (g, area) = tri_gradients(&std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]))?;
                let d = plane_strain(young, poisson);
                let rows: Vec<&[f64]> = d.iter().map(|r| r.as_slice()).collect();
                gauss_shape_gradient(&[(g, area * section.thickness)], &rows, None, ws, u)
            }
            Element::Tet4 => {
                let (g, volume) = tet_gradients(&std::array::from_fn(|k| {
                    [x[3 * k], x[3 * k + 1], x[3 * k + 2]]
                }))?;
                let d = isotropic(young, poisson);
                let rows: Vec<&[f64]> = d.iter().map(|r| r.as_slice()).collect();
                gauss_shape_gradient(&[(g, volume)], &rows, None, ws, u)
            }
        }
    }

    /// The element's area (2D, per unit thickness) or volume: the sum of the
    /// weights of [`Element::load_points`]. None for an inverted or
    /// degenerate element (a weight not positive), as [`Element::stiffness`]
    /// refuses it: a mesh importer checks its elements with it.
    pub fn measure<T: Scalar>(self, x: &[T]) -> Option<T> {
        let points = self.load_points(x);
        if !points
            .iter()
            .all(|p| p.1.re() > 0.0 && p.1.re().is_finite())
        {
            return None;
        }
        let mut sum = T::from(0.0);
        for (_, w) in points {
            sum += w;
        }
        Some(sum)
    }

    /// The points of the rule that integrates body loads: each with the
    /// shape-function values there and its weight (`det J` times the Gauss
    /// weight, signed), so that `int N_k b dV = sum w N_k b` for a uniform
    /// `b` (times the thickness in 2D). The bricks' 2x2 and 2x2x2 Gauss
    /// points as [`quad_gauss`] and [`hex_gauss`] give them; the simplices'
    /// centroid, weighted by the measure (exact: `N_k` is linear).
    pub fn load_points<T: Scalar>(self, x: &[T]) -> Vec<(Vec<f64>, T)> {
        let c2 = |k: usize| [x[2 * k], x[2 * k + 1]];
        let c3 = |k: usize| [x[3 * k], x[3 * k + 1], x[3 * k + 2]];
        match self {
            Element::Quad4 => into_vec(quad_gauss(&std::array::from_fn(c2))),
            Element::Hex8 => into_vec(hex_gauss(&std::array::from_fn(c3))),
            Element::Tri3 => into_vec(tri_gauss(&std::array::from_fn(c2))),
            Element::Tet4 => into_vec(tet_gauss(&std::array::from_fn(c3))),
        }
    }

    /// The strain at the element's centre (Voigt with engineering shears: xx,
    /// yy, xy in 2D; xx, yy, zz, yz, xz, xy in 3D) at element displacements
    /// `u`: where stresses are reported. The bricks' at the reference centre
    /// (as [`quad_strain_at`] and [`hex_strain_at`] at 0); a simplex's strain
    /// is the same everywhere. None for an inverted or degenerate element.
    pub fn centre_strain(self, x: &[f64], u: &[f64]) -> Option<Vec<f64>> {
        self.measure(x)?;
        let strain = match self {
            Element::Quad4 => quad_strain_at(
                &std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]),
                &std::array::from_fn(|i| u[i]),
                0.0,
                0.0,
            )
            .to_vec(),
            Element::Hex8 => hex_strain_at(
                &std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]),
                &std::array::from_fn(|i| u[i]),
                [0.0; 3],
            )
            .to_vec(),
            Element::Tri3 => tri_strain(
                &std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]),
                &std::array::from_fn(|i| u[i]),
            )?
            .to_vec(),
            Element::Tet4 => tet_strain(
                &std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]),
                &std::array::from_fn(|i| u[i]),
            )?
            .to_vec(),
        };
        Some(strain)
    }
}

/// Rule points with their shape values as vectors (one type for every element).
fn into_vec<T, const N: usize>(points: Vec<([f64; N], T)>) -> Vec<(Vec<f64>, T)> {
    points.into_iter().map(|(n, w)| (n.to_vec(), w)).collect()
}

/// [`bilinear_shape_gradient`] over the Gauss `points`, plus B-bar's mean
/// dilatation term where `kappa` (the bulk modulus) is given. None for an
/// inverted or degenerate element.
fn gauss_shape_gradient<const D: usize, const N: usize>(
    points: &[([[f64; D]; N], f64)],
    d: &[&[f64]],
    kappa: Option<f64>,
    ws: &[&[f64]],
    u: &[f64],
) -> Option<Vec<Vec<f64>>> {
    if !points.iter().all(|p| p.1 > 0.0 && p.1.is_finite()) {
        return None;
    }
    let mut out = bilinear_shape_gradient(points, d, ws, u);
    if let Some(kappa) = kappa {
        mean_dilatation_shape_gradient(points, kappa, ws, u, &mut out);
    }
    Some(out)
}

/// B-bar's volumetric stiffness `scale * c c^T / volume` added to `k` (dense,
/// row-major, `c.len()` square, symmetric and kept so bit for bit): the mean
/// dilatation `c . u / volume` times the bulk modulus (`scale`, times the
/// thickness in 2D) over the element.
fn add_mean_dilatation<T: Scalar>(k: &mut [T], c: &[T], volume: T, scale: f64) {
    let n = c.len();
    let s: Vec<T> = c.iter().map(|&ca| ca * scale / volume).collect();
    for a in 0..n {
        for b in a..n {
            let v = s[a] * c[b];
            k[a * n + b] += v;
            if b != a {
                k[b * n + a] += v;
            }
        }
    }
}

/// Rigid motions in `dim` dimensions: translations and rotations.
pub fn rigid_modes(dim: usize) -> usize {
    dim * (dim + 1) / 2
}
