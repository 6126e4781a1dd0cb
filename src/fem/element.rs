//! The element types a subdomain is assembled from, behind one interface: the
//! solver asks an [`Element`] for its size and its stiffness, never whether the
//! scene is 2D or 3D. Adding the trilinear hexahedron adds a variant here (and
//! its routine beside [`super::quad`]); nothing in `tfeti/` changes, as the
//! hexahedron showed.

use super::hex::{hex_dilatation, hex_gradients, hex_stiffness, isotropic, isotropic_deviatoric};
use super::quad::{
    plane_strain, plane_strain_deviatoric, quad_dilatation, quad_gradients, quad_stiffness,
};
use super::shape_gradient::{bilinear_shape_gradient, mean_dilatation_shape_gradient};
use crate::num::Scalar;

/// An element type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Element {
    /// Bilinear quadrilateral, plane strain (2D, 4 nodes).
    Quad4,
    /// Trilinear hexahedron (3D, 8 nodes).
    Hex8,
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
    /// The element of a scene in `dim` dimensions (2: quadrilaterals, else
    /// hexahedra).
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
            Element::Quad4 => 2,
            Element::Hex8 => 3,
        }
    }

    /// Nodes per element.
    pub fn nodes(self) -> usize {
        match self {
            Element::Quad4 => 4,
            Element::Hex8 => 8,
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
        }
    }

    /// Whether this element has a formulation that does not lock near
    /// incompressibility (B-bar). Every element today; a linear triangle or
    /// tetrahedron would not, and the checker warns where it would be used.
    pub fn has_bbar(self) -> bool {
        match self {
            Element::Quad4 | Element::Hex8 => true,
        }
    }

    /// The formulation used for a material of Poisson's ratio `poisson`:
    /// `asked`, or where None (automatic) B-bar from [`NEARLY_INCOMPRESSIBLE`]
    /// on; never B-bar where the element has none.
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
    /// None for an inverted or degenerate element.
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
        };
        Some(c.iter().zip(u).map(|(a, b)| a * b).sum::<f64>() / volume)
    }

    /// `d(w^T K_e u) / dX` for every node coordinate (node-major, like `x`) and
    /// every `w` of `ws`, in one pass ([`super::shape_gradient`]); `w` and `u`
    /// are element vectors. None for an inverted or degenerate element.
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
        }
    }
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
