//! Subdomains of an imported body (issue 35): its cells cut into `n` parts by
//! METIS (k-way on the cell dual graph, [`Objective`] by cell kind;
//! tetrahedra on the graph of their compact [`aggregates`]), each part one
//! connected piece, the same cut for the same mesh every time.
//!
//! Connected parts matter to TFETI: a subdomain's kernel is its rigid modes,
//! and a part in two pieces has twice as many (the pieces float apart), which
//! the rigid modes computed from the subdomain's node coordinates would miss.
//! METIS is asked for connected parts where the mesh is connected, and
//! [`connect_parts`] checks and repairs what it returns all the same.

use crate::io::msh::{sorted_facets, CellKind};
use metis::option::{Contig, ObjType, Seed};
use metis::Idx;
use std::fmt;
use std::sync::Mutex;

mod aggregates;
use aggregates::Lumps;

/// The seed of METIS's random numbers: fixed, so that a mesh always gets the
/// same cut (and a report the same numbers).
const SEED: Idx = 20_240_035;

/// METIS keeps its random generator in a global (GKlib's `mt` array), and its
/// error path swaps process-wide signal handlers: two calls at once would race
/// (cuts that change from run to run, or worse). Every call holds this lock.
static METIS_LOCK: Mutex<()> = Mutex::new(());

/// The cell dual graph in compressed rows: cells are adjacent when they share
/// a facet (an edge in 2D, a face in 3D). Sharing only a node or an edge in 3D
/// does not count: such cells do not hold each other.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DualGraph {
    /// Row starts: the neighbours of cell `c` are `adjncy[xadj[c]..xadj[c + 1]]`.
    pub xadj: Vec<usize>,
    /// Neighbours, sorted within each row, each once.
    pub adjncy: Vec<usize>,
}

impl DualGraph {
    /// The dual graph of `cells` (node indices per cell, of one `kind`), from
    /// the facets sorted by their node keys: two cells with equal keys share
    /// that facet.
    pub fn new(kind: CellKind, cells: &[Vec<usize>]) -> DualGraph {
        let facets = sorted_facets(kind, cells);
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        for run in facets.chunk_by(|a, b| a.key == b.key) {
            for (i, a) in run.iter().enumerate() {
                for b in &run[i + 1..] {
                    if a.cell != b.cell {
                        pairs.push((a.cell, b.cell));
                        pairs.push((b.cell, a.cell));
                    }
                }
            }
        }
        DualGraph::from_pairs(cells.len(), pairs)
    }

    /// The graph of `n` vertices with the edges `pairs` (both directions
    /// listed; in any order, repeats allowed).
    fn from_pairs(n: usize, mut pairs: Vec<(usize, usize)>) -> DualGraph {
        pairs.sort_unstable();
        pairs.dedup();
        let mut xadj = vec![0; n + 1];
        for &(a, _) in &pairs {
            xadj[a + 1] += 1;
        }
        for c in 0..n {
            xadj[c + 1] += xadj[c];
        }
        DualGraph {
            xadj,
            adjncy: pairs.into_iter().map(|(_, b)| b).collect(),
        }
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.xadj.len().saturating_sub(1)
    }

    /// The cells that share a facet with cell `c`.
    pub fn neighbours(&self, c: usize) -> &[usize] {
        match (self.xadj.get(c), self.xadj.get(c + 1)) {
            (Some(&a), Some(&b)) => &self.adjncy[a..b],
            _ => &[],
        }
    }

    /// Connected pieces of the cells for which `keep` holds, joined through
    /// neighbours that also keep: each kept cell's piece number (pieces
    /// numbered in the order of their first cell), `usize::MAX` for the others;
    /// and each piece's cells.
    fn pieces(&self, keep: impl Fn(usize, usize) -> bool) -> (Vec<usize>, Vec<Vec<usize>>) {
        let mut piece_of = vec![usize::MAX; self.cells()];
        let mut pieces: Vec<Vec<usize>> = Vec::new();
        for start in 0..self.cells() {
            if piece_of[start] != usize::MAX {
                continue;
            }
            let id = pieces.len();
            piece_of[start] = id;
            let mut members = vec![start];
            let mut next = 0;
            while let Some(&c) = members.get(next) {
                next += 1;
                for &d in self.neighbours(c) {
                    if piece_of[d] == usize::MAX && keep(c, d) {
                        piece_of[d] = id;
                        members.push(d);
                    }
                }
            }
            pieces.push(members);
        }
        (piece_of, pieces)
    }
}

/// A cut of a body's cells into subdomains.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Partition {
    /// The subdomain (0..n) of each cell.
    pub part_of_cell: Vec<usize>,
    /// Pieces that METIS left apart from the rest of their part and that were
    /// moved to a neighbouring part (0 usually; worth a note when not).
    pub moved_pieces: usize,
}

impl Partition {
    /// Cells per subdomain.
    pub fn sizes(&self, parts: usize) -> Vec<usize> {
        part_sizes(&self.part_of_cell, parts)
    }
}

/// Cells per part (parts numbered below `parts`; others not counted).
fn part_sizes(part_of_cell: &[usize], parts: usize) -> Vec<usize> {
    let mut sizes = vec![0; parts];
    for &p in part_of_cell {
        if let Some(s) = sizes.get_mut(p) {
            *s += 1;
        }
    }
    sizes
}

/// Why a body cannot be cut as asked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PartitionError {
    /// `subdomains = 0`.
    NoParts,
    /// More subdomains than cells.
    TooManyParts { parts: usize, cells: usize },
    /// A mesh whose pieces float apart needs a subdomain per piece at least.
    TooFewParts { parts: usize, pieces: usize },
    /// Pieces that share no facet but touch at a node (or an edge): they can
    /// neither float apart nor hold each other. `node` indexes the body's nodes.
    TouchingPieces { node: usize },
    /// METIS failed (its message), or the mesh is too large for its indices.
    Metis(String),
    /// METIS left a subdomain without cells.
    EmptyPart { part: usize, parts: usize },
    /// A subdomain in pieces that share no facet with another subdomain: the
    /// mesh itself is in pieces (cut each piece on its own).
    Disconnected { part: usize, pieces: usize },
}

impl std::error::Error for PartitionError {}

impl fmt::Display for PartitionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PartitionError::NoParts => write!(f, "a body needs at least 1 subdomain"),
            PartitionError::TooManyParts { parts, cells } => write!(
                f,
                "{parts} subdomains for {cells} elements: a subdomain needs at least one \
                 element; ask for at most {cells}"
            ),
            PartitionError::TooFewParts { parts, pieces } => write!(
                f,
                "{parts} subdomains for a mesh of {pieces} separate pieces: each piece needs \
                 its own; ask for at least {pieces}"
            ),
            PartitionError::TouchingPieces { node } => write!(
                f,
                "the mesh's pieces touch at a node (the body's node {node}) without sharing a \
                 face: they can neither float apart nor hold each other; mesh them apart or \
                 as one piece"
            ),
            PartitionError::Metis(m) => write!(f, "METIS could not cut the mesh: {m}"),
            PartitionError::EmptyPart { part, parts } => write!(
                f,
                "METIS left subdomain {part} of {parts} empty: ask for fewer subdomains"
            ),
            PartitionError::Disconnected { part, pieces } => write!(
                f,
                "subdomain {part} is in {pieces} pieces and the mesh too: a body's mesh must be \
                 one piece to be cut into subdomains"
            ),
        }
    }
}

/// Cuts `cells` (of one `kind`) into `n` connected subdomains. Given the
/// node coordinates, tetrahedra are cut on the graph of their compact
/// [`aggregates`] (METIS on the cells themselves without them).
pub fn partition(
    kind: CellKind,
    cells: &[Vec<usize>],
    nodes: Option<&[[f64; 3]]>,
    n: usize,
) -> Result<Partition, PartitionError> {
    if n == 0 {
        return Err(PartitionError::NoParts);
    }
    if n > cells.len() {
        return Err(PartitionError::TooManyParts {
            parts: n,
            cells: cells.len(),
        });
    }
    let graph = DualGraph::new(kind, cells);
    let mut part_of_cell = if n == 1 {
        vec![0; cells.len()]
    } else if let Some(cut) = nodes
        .and_then(|x| Lumps::of(kind, &graph, cells, x, n))
        .and_then(|lumps| lumps.cut(n, Objective::of(kind)))
    {
        cut
    } else {
        metis_kway(&graph, n, Objective::of(kind), None)?
    };
    if let Some(part) = part_sizes(&part_of_cell, n).iter().position(|&s| s == 0) {
        return Err(PartitionError::EmptyPart { part, parts: n });
    }
    let moved_pieces = connect_parts(&graph, &mut part_of_cell)?;
    Ok(Partition {
        part_of_cell,
        moved_pieces,
    })
}

/// A mesh in pieces (each floats on its own) cut into `n` subdomains: each
/// piece gets a share of them in proportion to its cells (at least one), and
/// is cut on its own by [`partition`], so no subdomain spans two pieces.
/// Parts are numbered piece after piece, in the order of the pieces' first
/// cells.
///
/// # Errors
/// Fewer subdomains than pieces ([`PartitionError::TooFewParts`]), and what
/// [`partition`] refuses for a piece.
pub fn partition_pieces(
    kind: CellKind,
    cells: &[Vec<usize>],
    nodes: Option<&[[f64; 3]]>,
    n: usize,
) -> Result<Partition, PartitionError> {
    let graph = DualGraph::new(kind, cells);
    let (_, pieces) = graph.pieces(|_, _| true);
    if pieces.len() <= 1 {
        return partition(kind, cells, nodes, n);
    }
    if n < pieces.len() {
        return Err(PartitionError::TooFewParts {
            parts: n,
            pieces: pieces.len(),
        });
    }
    if let Some(node) = shared_node(cells, &pieces) {
        return Err(PartitionError::TouchingPieces { node });
    }
    // One each, then each next one to the piece with the most cells per
    // subdomain that can still take one (no more subdomains than cells).
    let mut share = vec![1usize; pieces.len()];
    for _ in pieces.len()..n {
        let next = (0..pieces.len())
            .filter(|&p| share[p] < pieces[p].len())
            .max_by(|&a, &b| {
                let per = |p: usize| pieces[p].len() as f64 / share[p] as f64;
                per(a).total_cmp(&per(b)).then(b.cmp(&a))
            });
        let Some(p) = next else {
            return Err(PartitionError::TooManyParts {
                parts: n,
                cells: cells.len(),
            });
        };
        share[p] += 1;
    }
    let mut part_of_cell = vec![0; cells.len()];
    let (mut first, mut moved_pieces) = (0, 0);
    for (piece, &parts) in pieces.iter().zip(&share) {
        let sub: Vec<Vec<usize>> = piece.iter().map(|&c| cells[c].clone()).collect();
        let cut = partition(kind, &sub, nodes, parts)?;
        for (&c, &p) in piece.iter().zip(&cut.part_of_cell) {
            part_of_cell[c] = first + p;
        }
        first += parts;
        moved_pieces += cut.moved_pieces;
    }
    Ok(Partition {
        part_of_cell,
        moved_pieces,
    })
}

/// A node that cells of two pieces use (pieces that share no facet but touch
/// at a node or an edge), if any.
fn shared_node(cells: &[Vec<usize>], pieces: &[Vec<usize>]) -> Option<usize> {
    let mut piece_of_node: std::collections::HashMap<usize, usize> =
        std::collections::HashMap::new();
    for (p, piece) in pieces.iter().enumerate() {
        for &c in piece {
            for &n in &cells[c] {
                if *piece_of_node.entry(n).or_insert(p) != p {
                    return Some(n);
                }
            }
        }
    }
    None
}

/// What METIS minimizes for a kind of cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Objective {
    /// The facets cut (METIS's default).
    Cut,
    /// The communication volume: each cell counted once per other part it
    /// borders.
    Volume,
}

impl Objective {
    /// Simplices are cut by volume, quadrilaterals and hexahedra by facets.
    /// Measured with the default solver (BENCHMARKS.md, "Bodies from Gmsh
    /// files"): on Kuhn-split tetrahedral bricks the volume cut takes 195
    /// Hessian applications at 108 subdomains against 272 (119 against 137 at
    /// 32; 4 more at 13), about a third less time; on the hexahedra of the
    /// same bricks it takes fewer applications too (118 against 130) but its
    /// subdomains hold 11 % larger factors and 12 % more gluing rows, and
    /// the solve took longer in every run.
    fn of(kind: CellKind) -> Objective {
        match kind {
            CellKind::Tri3 | CellKind::Tet4 => Objective::Volume,
            CellKind::Quad4 | CellKind::Hex8 => Objective::Cut,
        }
    }
}

/// METIS_PartGraphKway with a fixed seed, the kind's [`Objective`], the
/// vertices' `weights` (1 each without) and
/// default balance (`ufactor` 30: parts within 3 % of the mean), asking for
/// connected parts where the graph is connected (METIS stops with an error
/// when asked that of a graph in pieces).
fn metis_kway(
    graph: &DualGraph,
    n: usize,
    objective: Objective,
    weights: Option<&[usize]>,
) -> Result<Vec<usize>, PartitionError> {
    let too_large = |_| PartitionError::Metis("the mesh is too large for METIS's indices".into());
    let xadj: Vec<Idx> = graph
        .xadj
        .iter()
        .map(|&x| Idx::try_from(x))
        .collect::<Result<_, _>>()
        .map_err(too_large)?;
    let adjncy: Vec<Idx> = graph
        .adjncy
        .iter()
        .map(|&x| Idx::try_from(x))
        .collect::<Result<_, _>>()
        .map_err(too_large)?;
    let nparts = Idx::try_from(n).map_err(too_large)?;
    if weights.is_some_and(|w| w.len() != graph.cells()) {
        return Err(PartitionError::Metis(
            "a weight per vertex is needed (cso's error)".into(),
        ));
    }
    let vwgt: Option<Vec<Idx>> = weights
        .map(|w| w.iter().map(|&x| Idx::try_from(x)).collect())
        .transpose()
        .map_err(too_large)?;
    let connected = graph.pieces(|_, _| true).1.len() <= 1;
    let mut part: Vec<Idx> = vec![0; graph.cells()];
    let _lock = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let mut kway = metis::Graph::new(1, nparts, &xadj, &adjncy)
        .map_err(|e| PartitionError::Metis(e.to_string()))?;
    if let Some(vwgt) = &vwgt {
        kway = kway.set_vwgt(vwgt);
    }
    kway.set_option(Seed(SEED))
        .set_option(Contig(connected))
        .set_option(match objective {
            Objective::Cut => ObjType::Cut,
            Objective::Volume => ObjType::Vol,
        })
        .part_kway(&mut part)
        .map_err(|e| PartitionError::Metis(e.to_string()))?;
    part.into_iter()
        .map(|p| usize::try_from(p).ok().filter(|&p| p < n))
        .collect::<Option<Vec<usize>>>()
        .ok_or_else(|| PartitionError::Metis("METIS returned a part out of range".into()))
}

/// Makes every part one connected piece: the largest piece of each part stays
/// (ties: the one with the lowest cell), every other piece moves to the
/// neighbouring part with which it shares most facets (ties: the lower part),
/// counted against the parts' staying pieces so that each move joins a piece
/// that stays; repeated until all parts are connected. Each move leaves one
/// piece fewer, so this ends. On a connected mesh every round moves one piece
/// at least: a cluster of moving cells has a staying neighbour, which is of
/// another part (were it of the same part, the moving cell would be in its
/// piece). So a round that moves nothing means the mesh itself is in pieces:
/// an error. Returns the pieces moved. Parts are numbered from 0, as METIS
/// numbers them.
pub fn connect_parts(
    graph: &DualGraph,
    part_of_cell: &mut [usize],
) -> Result<usize, PartitionError> {
    let mut moved = 0;
    loop {
        let parts = part_of_cell.iter().max().map_or(0, |p| p.saturating_add(1));
        let (piece_of, pieces) = graph.pieces(|c, d| part_of_cell[c] == part_of_cell[d]);
        let mut main: Vec<Option<usize>> = vec![None; parts];
        for (id, cells) in pieces.iter().enumerate() {
            let part = part_of_cell[cells[0]];
            if main[part].is_none_or(|m| pieces[m].len() < cells.len()) {
                main[part] = Some(id);
            }
        }
        let strays: Vec<usize> = (0..pieces.len())
            .filter(|&id| main[part_of_cell[pieces[id][0]]] != Some(id))
            .collect();
        if strays.is_empty() {
            return Ok(moved);
        }
        let stays = |d: usize| main[part_of_cell[d]] == Some(piece_of[d]);
        let targets: Vec<(usize, usize)> = strays
            .iter()
            .filter_map(|&id| {
                best_neighbour(graph, part_of_cell, &pieces[id], stays).map(|p| (id, p))
            })
            .collect();
        if targets.is_empty() {
            let part = part_of_cell[pieces[strays[0]][0]];
            let count = pieces.iter().filter(|p| part_of_cell[p[0]] == part).count();
            return Err(PartitionError::Disconnected {
                part,
                pieces: count,
            });
        }
        for (id, part) in &targets {
            for &c in &pieces[*id] {
                part_of_cell[c] = *part;
            }
        }
        moved += targets.len();
    }
}

/// The part, other than the piece's own, with which the piece shares most
/// facets through cells for which `counts` holds (ties: the lower part).
fn best_neighbour(
    graph: &DualGraph,
    part_of_cell: &[usize],
    piece: &[usize],
    counts: impl Fn(usize) -> bool,
) -> Option<usize> {
    let own = part_of_cell[*piece.first()?];
    let mut shared: Vec<(usize, usize)> = Vec::new();
    for &c in piece {
        for &d in graph.neighbours(c) {
            let p = part_of_cell[d];
            if p == own || !counts(d) {
                continue;
            }
            match shared.iter_mut().find(|(q, _)| *q == p) {
                Some((_, n)) => *n += 1,
                None => shared.push((p, 1)),
            }
        }
    }
    shared
        .into_iter()
        .max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))
        .map(|(p, _)| p)
}

#[cfg(test)]
mod tests;

/// METIS's nested dissection of a mesh's node graph (nodes adjacent where
/// they share an element; `per` nodes per element): the order in which to
/// eliminate the nodes, for a subdomain factor that no brick lattice orders.
/// None where METIS fails or the mesh is too small or too large for its
/// indices. Its random choices are seeded, so an order repeats.
pub fn node_dissection(elements: &[usize], per: usize, nodes: usize) -> Option<Vec<usize>> {
    if nodes < 3 || per == 0 {
        return None;
    }
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nodes];
    for e in elements.chunks_exact(per) {
        for &a in e {
            for &b in e {
                if a != b {
                    adj.get_mut(a)?.push(b);
                }
            }
        }
    }
    let mut xadj: Vec<Idx> = Vec::with_capacity(nodes + 1);
    let mut adjncy: Vec<Idx> = Vec::new();
    xadj.push(0);
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
        for &b in a.iter() {
            adjncy.push(Idx::try_from(b).ok()?);
        }
        xadj.push(Idx::try_from(adjncy.len()).ok()?);
    }
    let mut n = Idx::try_from(nodes).ok()?;
    let mut options = [0 as Idx; metis_sys::METIS_NOPTIONS as usize];
    let (mut perm, mut iperm) = (vec![0 as Idx; nodes], vec![0 as Idx; nodes]);
    let _lock = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: the arrays have the lengths METIS_NodeND reads and writes
    // (xadj: nodes + 1; adjncy: xadj[nodes]; options: METIS_NOPTIONS; perm
    // and iperm: nodes), a null vwgt means unit weights, and the lock keeps
    // METIS's globals to one caller.
    let status = unsafe {
        metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
        options[metis_sys::moptions_et_METIS_OPTION_SEED as usize] = SEED;
        options[metis_sys::moptions_et_METIS_OPTION_NUMBERING as usize] = 0;
        metis_sys::METIS_NodeND(
            &mut n,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return None;
    }
    // perm[k]: the node eliminated k-th.
    perm.into_iter().map(|v| usize::try_from(v).ok()).collect()
}
