//! The compiled contact problem for other solvers: the primal QP of the state
//!
//! ```text
//! min 1/2 u^T K u - f^T u   s.t.   B_E u = c_E,   B_I u <= c_I
//! ```
//!
//! with `K` block diagonal by subdomain (each subdomain owns copies of its
//! nodes; gluing rows of `B_E` tie them), the kernel basis `R` (orthonormal rigid
//! motions of every subdomain, `K R = 0`), and a manifest (`manifest.json`) that
//! says which file is what, the sizes, the sign conventions and the scale of
//! every row. Rows are normalized (`||B_i|| = 1`); the physical force of row `i`
//! is `lambda_i / scale_i` (N), with `lambda_I >= 0` pushing the bodies apart.
//!
//! Formats: PETSc binary as PETSc writes it (big-endian, 32-bit indices; `Vec`
//! class id 1211214 then `n` and the values; AIJ `Mat` class id 1211216 then
//! `M, N, nnz`, the row counts, the column indices, the values) and MatrixMarket
//! (`coordinate real general` for matrices, `array real general` for vectors).

use crate::state::Setup;
use serde::Serialize;
use std::fmt::Write as _;

/// The file format of an export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// PETSc binary (`.bin`), readable by `PetscViewerBinaryOpen` / petsc4py.
    Petsc,
    /// MatrixMarket (`.mtx`), readable by scipy.io.mmread, Matlab, Julia.
    Mm,
}

/// A sparse matrix in compressed rows, columns sorted within each row.
#[derive(Debug, Clone, PartialEq)]
pub struct Csr {
    pub nrows: usize,
    pub ncols: usize,
    pub row_ptr: Vec<usize>,
    pub col: Vec<usize>,
    pub val: Vec<f64>,
}

impl Csr {
    /// From triplets (duplicates summed, exact zeros kept out).
    pub fn from_triplets(nrows: usize, ncols: usize, mut t: Vec<(usize, usize, f64)>) -> Csr {
        t.sort_by_key(|a| (a.0, a.1));
        let mut row_ptr = vec![0; nrows + 1];
        let (mut col, mut val): (Vec<usize>, Vec<f64>) = (Vec::new(), Vec::new());
        let mut last: Option<(usize, usize)> = None;
        let mut rows = Vec::new();
        for (r, c, v) in t {
            if last == Some((r, c)) {
                if let Some(x) = val.last_mut() {
                    *x += v;
                }
                continue;
            }
            last = Some((r, c));
            rows.push(r);
            col.push(c);
            val.push(v);
        }
        // Drop entries that summed to exactly zero.
        let keep: Vec<bool> = val.iter().map(|v| *v != 0.0).collect();
        let mut k = 0;
        let (mut c2, mut v2) = (Vec::with_capacity(col.len()), Vec::with_capacity(val.len()));
        for i in 0..col.len() {
            if keep[i] {
                row_ptr[rows[i] + 1] += 1;
                c2.push(col[i]);
                v2.push(val[i]);
                k += 1;
            }
        }
        debug_assert_eq!(k, c2.len());
        for r in 0..nrows {
            row_ptr[r + 1] += row_ptr[r];
        }
        Csr {
            nrows,
            ncols,
            row_ptr,
            col: c2,
            val: v2,
        }
    }

    pub fn nnz(&self) -> usize {
        self.col.len()
    }
}

/// What one row of `B` is, for the manifest.
#[derive(Debug, Clone, Serialize)]
pub struct RowInfo {
    /// `gluing`, `dirichlet`, `symmetry`, `tie`, `contact` or `friction`.
    pub kind: &'static str,
    /// The norm of the row before normalization: force = lambda / scale.
    pub scale: f64,
    /// A friction row: the index of its node's contact row among the rows
    /// of `B_I` (the rows of `B_T` of one node follow each other and share it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal_row: Option<usize>,
    /// A friction row: Tresca's bound on its node's tangential force (N).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip_bound: Option<f64>,
    /// A friction row: Coulomb's coefficient.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
}

/// The friction rows of a QP: `B_T` and per row its node's contact row
/// (among `B_I`'s), Tresca bound (N, 0 for Coulomb) and Coulomb coefficient
/// (0 for Tresca).
#[derive(Debug, Clone)]
pub struct FrictionRows {
    pub b_t: Csr,
    pub normal_row: Vec<f64>,
    pub slip_bound: Vec<f64>,
    pub coefficient: Vec<f64>,
}

/// The primal QP of a scene at a design.
#[derive(Debug, Clone)]
pub struct Qp {
    /// Primal dofs per subdomain (the diagonal blocks of `K`, in order).
    pub blocks: Vec<usize>,
    pub k: Csr,
    pub f: Vec<f64>,
    pub b_eq: Csr,
    pub c_eq: Vec<f64>,
    pub b_in: Csr,
    pub c_in: Vec<f64>,
    /// With friction: the tangential rows.
    pub friction: Option<FrictionRows>,
    /// Kernel basis, `n x (sum of kernel dimensions)`.
    pub r: Csr,
    pub rows: Vec<RowInfo>,
    /// Components per node (2 or 3), dofs interleaved per node.
    pub dim: usize,
}

/// The QP of a set-up problem (lowered and factorized; nothing solved).
pub fn primal_qp(setup: &Setup) -> Qp {
    let problem = &setup.problem;
    let cluster = &setup.cluster;
    let blocks: Vec<usize> = (0..cluster.len()).map(|s| cluster.dofs(s)).collect();
    let mut offset = vec![0];
    for b in &blocks {
        offset.push(offset[offset.len() - 1] + b);
    }
    let n = offset[blocks.len()];
    let per: Vec<Vec<(usize, usize, f64)>> = cluster.map(|s, sub| {
        let k = sub.stiffness();
        let o = offset[s];
        let mut t = Vec::with_capacity(2 * k.values.len());
        for c in 0..k.n {
            for p in k.col_ptr[c]..k.col_ptr[c + 1] {
                let (r, v) = (k.row_idx[p], k.values[p]);
                t.push((o + r, o + c, v));
                if r != c {
                    t.push((o + c, o + r, v));
                }
            }
        }
        t
    });
    let k = Csr::from_triplets(n, n, per.into_iter().flatten().collect());
    let f: Vec<f64> = problem
        .subdomains
        .iter()
        .flat_map(|m| m.f.iter().copied())
        .collect();
    let offset = &offset;
    let b = |range: std::ops::Range<usize>| {
        let nrows = range.len();
        let mut t = Vec::new();
        for (i, r) in range.clone().enumerate() {
            for &(s, d, v) in &problem.rows[r].entries {
                t.push((i, offset[s] + d, v));
            }
        }
        let c = range.map(|r| problem.rows[r].c).collect();
        (Csr::from_triplets(nrows, n, t), c)
    };
    let ne = problem.n_equality;
    // Friction rows follow every other row.
    let nc = problem
        .rows
        .iter()
        .position(|r| matches!(r.kind, crate::model::RowKind::Friction { .. }))
        .unwrap_or(problem.rows.len());
    let (b_eq, c_eq) = b(0..ne);
    let (b_in, c_in) = b(ne..nc);
    let friction =
        (nc < problem.rows.len()).then(|| friction_rows(problem, nc, b(nc..problem.rows.len()).0));
    let modes: Vec<usize> = (0..cluster.len())
        .map(|s| cluster.subdomain(s).kernel_dim())
        .collect();
    let mut rt = Vec::new();
    let mut col0 = 0;
    for s in 0..cluster.len() {
        let sub = cluster.subdomain(s);
        for j in 0..modes[s] {
            for (d, v) in sub.kernel_column(j).iter().enumerate() {
                rt.push((offset[s] + d, col0 + j, *v));
            }
        }
        col0 += modes[s];
    }
    let r = Csr::from_triplets(n, col0, rt);
    let rows = problem.rows.iter().map(|row| row_info(row, ne)).collect();
    Qp {
        blocks,
        k,
        f,
        b_eq,
        c_eq,
        b_in,
        c_in,
        friction,
        r,
        rows,
        dim: problem.dim,
    }
}

/// The friction rows `nc..` of `problem` (after every other row), with
/// `b_t` their matrix: per row its node's contact row among `B_I`'s (`B_I`
/// starts at `n_equality`), Tresca bound and Coulomb coefficient.
fn friction_rows(problem: &crate::model::Problem, nc: usize, b_t: Csr) -> FrictionRows {
    let mut f = FrictionRows {
        b_t,
        normal_row: Vec::new(),
        slip_bound: Vec::new(),
        coefficient: Vec::new(),
    };
    for row in &problem.rows[nc..] {
        if let crate::model::RowKind::Friction {
            normal_row, law, ..
        } = row.kind
        {
            f.normal_row.push((normal_row - problem.n_equality) as f64);
            let (g, mu) = match law {
                crate::model::SlipLaw::Tresca(g) => (g, 0.0),
                crate::model::SlipLaw::Coulomb(mu) => (0.0, mu),
            };
            f.slip_bound.push(g);
            f.coefficient.push(mu);
        }
    }
    f
}

/// What the manifest says of one row (`ne` equality rows come first).
fn row_info(row: &crate::model::Row, ne: usize) -> RowInfo {
    use crate::model::{RowKind, SlipLaw};
    let (normal_row, slip_bound, friction) = match row.kind {
        RowKind::Friction {
            normal_row, law, ..
        } => match law {
            SlipLaw::Tresca(g) => (Some(normal_row - ne), Some(g), None),
            SlipLaw::Coulomb(mu) => (Some(normal_row - ne), None, Some(mu)),
        },
        _ => (None, None, None),
    };
    RowInfo {
        kind: match row.kind {
            RowKind::Gluing => "gluing",
            RowKind::Dirichlet => "dirichlet",
            RowKind::Symmetry => "symmetry",
            RowKind::Tie { .. } => "tie",
            RowKind::Contact { .. } => "contact",
            RowKind::Friction { .. } => "friction",
        },
        scale: row.scale,
        normal_row,
        slip_bound,
        friction,
    }
}

/// The manifest: what a reader needs to rebuild and interpret the QP.
#[derive(Debug, Clone, Serialize)]
pub struct Manifest {
    pub scene: String,
    pub format: &'static str,
    pub problem: &'static str,
    pub conventions: Vec<&'static str>,
    pub primal: usize,
    pub equalities: usize,
    pub inequalities: usize,
    /// With friction: the rows of `B_T`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<usize>,
    pub kernel: usize,
    pub dim: usize,
    pub blocks: Vec<usize>,
    /// Which file holds what: (file, meaning).
    pub files: Vec<(String, &'static str)>,
    /// Per row of `[B_E; B_I]` (and `B_T` with friction): kind and scale.
    pub rows: Vec<RowInfo>,
    pub design: Vec<(String, f64)>,
}

/// The files of an export: `(name, bytes)`, the manifest last.
///
/// # Errors
/// When the manifest cannot be serialized (a bug).
pub fn files(
    qp: &Qp,
    format: Format,
    header: &crate::io::provenance::Header,
    scene: &str,
    design: Vec<(String, f64)>,
) -> Result<Vec<(String, Vec<u8>)>, serde_json::Error> {
    let ext = match format {
        Format::Petsc => "bin",
        Format::Mm => "mtx",
    };
    let mat = |m: &Csr| match format {
        Format::Petsc => petsc_mat(m),
        Format::Mm => mm_mat(m),
    };
    let vec = |v: &[f64]| match format {
        Format::Petsc => petsc_vec(v),
        Format::Mm => mm_vec(v),
    };
    let mut parts: Vec<(&str, &'static str, Vec<u8>)> = vec![
        (
            "K",
            "stiffness, symmetric, block diagonal by subdomain (blocks)",
            mat(&qp.k),
        ),
        ("f", "load vector (N)", vec(&qp.f)),
        (
            "BE",
            "equality rows: B_E u = c_E (gluing, supports, ties)",
            mat(&qp.b_eq),
        ),
        ("cE", "right-hand side of the equalities (m)", vec(&qp.c_eq)),
        (
            "BI",
            "contact rows: B_I u <= c_I (non-penetration)",
            mat(&qp.b_in),
        ),
        (
            "cI",
            "right-hand side of the contact rows: initial normal gaps (m)",
            vec(&qp.c_in),
        ),
        (
            "R",
            "kernel basis of K: orthonormal rigid motions per subdomain, K R = 0",
            mat(&qp.r),
        ),
    ];
    if let Some(f) = &qp.friction {
        parts.extend([
            (
                "BT",
                "friction rows (tangential, normalized): B_T u is the slip of each contact node along its tangents (one row in 2D, two in 3D, or one where a support holds the other direction)",
                mat(&f.b_t),
            ),
            (
                "nT",
                "per row of B_T: the index of its node's contact row among the rows of B_I",
                vec(&f.normal_row),
            ),
            (
                "gT",
                "per row of B_T: Tresca's bound on its node's tangential force (N; 0 for Coulomb rows)",
                vec(&f.slip_bound),
            ),
            (
                "muT",
                "per row of B_T: Coulomb's coefficient (0 for Tresca rows)",
                vec(&f.coefficient),
            ),
        ]);
    }
    let mut out: Vec<(String, Vec<u8>)> = Vec::new();
    let mut listed = Vec::new();
    for (name, what, bytes) in parts {
        let file = format!("{name}.{ext}");
        listed.push((file.clone(), what));
        out.push((file, bytes));
    }
    let manifest = Manifest {
        scene: scene.to_string(),
        format: match format {
            Format::Petsc => "petsc binary (big-endian, 32-bit indices, AIJ matrices, Vec vectors)",
            Format::Mm => "MatrixMarket (coordinate real general; vectors as array real general)",
        },
        problem: if qp.friction.is_some() {
            "min 1/2 u^T K u - f^T u  s.t.  B_E u = c_E,  B_I u <= c_I, with friction: the multipliers lambda_T of each node's rows of B_T (scaled to forces by scale) within |lambda_T / scale| <= g (Tresca: gT; Coulomb: muT times the node's normal force lambda_I / scale), a box in 2D and a disc in 3D"
        } else {
            "min 1/2 u^T K u - f^T u  s.t.  B_E u = c_E,  B_I u <= c_I"
        },
        conventions: [
            "u: displacements, dofs interleaved per node, subdomain blocks in order (each subdomain owns copies of its interface nodes; gluing rows of B_E tie them)",
            "rows of B are normalized (unit Euclidean norm); the physical multiplier (force, N) of row i is lambda_i / scale_i",
            if qp.friction.is_some() {
                "KKT: K u - f + B_E^T lambda_E + B_I^T lambda_I + B_T^T lambda_T = 0, lambda_I >= 0, lambda_I (B_I u - c_I) = 0; per node, B_T u = 0 where |lambda_T| is inside its bound, B_T u along lambda_T where it is on it"
            } else {
                "KKT: K u - f + B_E^T lambda_E + B_I^T lambda_I = 0, lambda_I >= 0, lambda_I (B_I u - c_I) = 0"
            },
            "R: orthonormal columns spanning the kernel of each diagonal block of K",
        ]
        .to_vec(),
        primal: qp.k.nrows,
        equalities: qp.b_eq.nrows,
        inequalities: qp.b_in.nrows,
        friction: qp.friction.as_ref().map(|f| f.b_t.nrows),
        kernel: qp.r.ncols,
        dim: qp.dim,
        blocks: qp.blocks.clone(),
        files: listed,
        rows: qp.rows.clone(),
        design,
    };
    let json = crate::io::provenance::to_json(header, &manifest)?;
    out.push(("manifest.json".to_string(), json.into_bytes()));
    Ok(out)
}

/// Exports the state problem of `scene` at `design`: lowered and factorized
/// (the kernel basis comes with the subdomains), not solved.
pub fn export(
    scene: &crate::lang::Scene,
    design: &[f64],
    format: Format,
) -> Result<Vec<(String, Vec<u8>)>, crate::state::SolveError> {
    let setup = crate::state::setup(scene, design)?;
    let qp = primal_qp(&setup);
    let named = scene
        .design
        .iter()
        .zip(design)
        .map(|(d, v)| (d.name.clone(), *v))
        .collect();
    let header = crate::io::provenance::Header::of(
        scene,
        "export",
        &[("length", "m"), ("force", "N"), ("pressure", "Pa")],
    );
    files(&qp, format, &header, &scene.name, named).map_err(|e| {
        crate::state::SolveError::Unsupported(format!("cannot write the manifest: {e}"))
    })
}

/// Checks, before anything is computed, that `dir` can take an export: a
/// directory that holds files cso did not write there is refused unless
/// `force`, so an export never mixes with other files (what an earlier cso
/// command wrote there is removed when the command opens the folder,
/// [`super::outputs`]); otherwise it is created and probed
/// ([`super::atomic::prepare_dir`]).
pub fn check_dir(dir: &std::path::Path, force: bool) -> std::io::Result<()> {
    if !force && dir.is_dir() && super::outputs::holds_other_files(dir)? {
        return Err(std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            format!(
                "{} holds files cso did not write; choose another directory or pass --force",
                dir.display()
            ),
        ));
    }
    super::atomic::prepare_dir(dir)
}

/// Writes `files` into `dir` (see [`check_dir`]), each atomically.
pub fn write_dir(
    dir: &std::path::Path,
    files: &[(String, Vec<u8>)],
    force: bool,
) -> std::io::Result<()> {
    check_dir(dir, force)?;
    for (name, bytes) in files {
        super::atomic::write_atomic(&dir.join(name), bytes)?;
    }
    Ok(())
}

const VEC_CLASSID: i32 = 1_211_214;
const MAT_CLASSID: i32 = 1_211_216;

fn be_i32(out: &mut Vec<u8>, v: usize) {
    out.extend_from_slice(&(v as i32).to_be_bytes());
}

/// A PETSc binary `Vec`.
pub fn petsc_vec(v: &[f64]) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 + 8 * v.len());
    out.extend_from_slice(&VEC_CLASSID.to_be_bytes());
    be_i32(&mut out, v.len());
    for x in v {
        out.extend_from_slice(&x.to_be_bytes());
    }
    out
}

/// A PETSc binary AIJ `Mat`.
pub fn petsc_mat(m: &Csr) -> Vec<u8> {
    let mut out = Vec::with_capacity(16 + 4 * m.nrows + 12 * m.nnz());
    out.extend_from_slice(&MAT_CLASSID.to_be_bytes());
    be_i32(&mut out, m.nrows);
    be_i32(&mut out, m.ncols);
    be_i32(&mut out, m.nnz());
    for r in 0..m.nrows {
        be_i32(&mut out, m.row_ptr[r + 1] - m.row_ptr[r]);
    }
    for &c in &m.col {
        be_i32(&mut out, c);
    }
    for x in &m.val {
        out.extend_from_slice(&x.to_be_bytes());
    }
    out
}

/// A MatrixMarket coordinate matrix (1-based, full precision).
pub fn mm_mat(m: &Csr) -> Vec<u8> {
    let mut s = String::with_capacity(40 * m.nnz() + 64);
    s.push_str("%%MatrixMarket matrix coordinate real general\n");
    let _ = writeln!(s, "{} {} {}", m.nrows, m.ncols, m.nnz());
    for r in 0..m.nrows {
        for p in m.row_ptr[r]..m.row_ptr[r + 1] {
            let _ = writeln!(s, "{} {} {:e}", r + 1, m.col[p] + 1, m.val[p]);
        }
    }
    s.into_bytes()
}

/// A MatrixMarket dense column vector.
pub fn mm_vec(v: &[f64]) -> Vec<u8> {
    let mut s = String::with_capacity(24 * v.len() + 64);
    s.push_str("%%MatrixMarket matrix array real general\n");
    let _ = writeln!(s, "{} 1", v.len());
    for x in v {
        let _ = writeln!(s, "{x:e}");
    }
    s.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triplets_are_summed_sorted_and_zeros_dropped() {
        let m = Csr::from_triplets(
            2,
            3,
            vec![
                (1, 2, 1.0),
                (0, 1, 2.0),
                (1, 2, 0.5),
                (0, 0, 1.0),
                (0, 0, -1.0),
            ],
        );
        assert_eq!(m.row_ptr, vec![0, 1, 2]);
        assert_eq!(m.col, vec![1, 2]);
        assert_eq!(m.val, vec![2.0, 1.5]);
    }

    #[test]
    fn petsc_headers_are_big_endian_with_the_class_ids() {
        let v = petsc_vec(&[1.0, -2.0]);
        assert_eq!(&v[..8], &[0, 0x12, 0x7b, 0x4e, 0, 0, 0, 2]);
        assert_eq!(&v[8..16], &1.0f64.to_be_bytes());
        let m = petsc_mat(&Csr::from_triplets(2, 2, vec![(0, 1, 3.0)]));
        // 1211216 = 0x127b50; M = 2, N = 2, nnz = 1, row counts 1, 0, column 1.
        assert_eq!(
            &m[..32],
            &[
                0, 0x12, 0x7b, 0x50, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0,
                0, 0, 1, 0x40, 0x08, 0, 0
            ]
        );
    }

    #[test]
    fn matrix_market_is_one_based() {
        let s = String::from_utf8(mm_mat(&Csr::from_triplets(2, 2, vec![(1, 0, 0.25)])))
            .expect("utf-8");
        assert_eq!(
            s,
            "%%MatrixMarket matrix coordinate real general\n2 2 1\n2 1 2.5e-1\n"
        );
    }
}
