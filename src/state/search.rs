//! The contact search loop on the deformed configuration. Lowering gives a
//! contact row only to the secondary nodes within the search distance of the
//! primary side at the start (the contact's `search`, or a first guess from the
//! secondary body's size); how far the bodies move is known only after the
//! solve. So after each state solve, the nodes without a row are checked
//! against the primary side at the computed displacements
//! ([`crate::model::unheld`]); where one ends inside, that contact's search is
//! widened past the displacements and the state solved again (on the same
//! factorizations), at most [`MAX_ROUNDS`] times, else the solve is refused.
//! The check reads the gathered displacements, which every rank holds, so a
//! distributed solve takes the same decision on every rank.

use super::{solve_on, Refactor, Round, SolveError, SolveOptions, State, WarmStart};
use crate::lang::scene::Scene;
use crate::model::{unheld, SearchFindings, Unheld};
use crate::qp::QpInfo;
use crate::tfeti::comm::Comm;
use std::borrow::Cow;
use std::sync::Arc;
use std::time::Instant;

/// Solves repeated with a wider search, at most.
pub const MAX_ROUNDS: usize = 4;

/// How far a widened search reaches beyond what it must cover.
const MARGIN: f64 = 1.25;

/// What the search loop did.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Search {
    /// Solves repeated with a wider search (0: the first one settled).
    pub rounds: usize,
    /// Per contact, the search distance the loop set (None: the scene's own,
    /// its `search` or the default). A solve from this state
    /// ([`super::SolveOptions::previous`]) starts from them, so that its rows, and so
    /// its warm start, match this state's.
    pub widened: Vec<Option<f64>>,
}

/// The state solve with the search loop: [`solve_on`], then at most
/// `options.search_rounds` solves with wider searches until no secondary node without a
/// row ends inside its primary side. Later rounds reuse the previous round's
/// factorizations (same design, same meshes); their rows differ, so their
/// dual solves start cold. The state's counts and times are the whole
/// loop's; its factorization counts are the first round's (the others
/// reuse them).
pub(super) fn solve_searching(
    scene: &Scene,
    design: &[f64],
    options: &SolveOptions,
    comm: Arc<dyn Comm>,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<State, SolveError> {
    let (previous, max_rounds) = (options.previous, options.search_rounds);
    let t0 = Instant::now();
    let n = scene.contacts.len();
    let mut widened = previous
        .map(|p| p.search.widened.clone())
        .filter(|w| w.len() == n)
        .unwrap_or_else(|| vec![None; n]);
    let mut state = solve_on(
        &widened_scene(scene, &widened),
        design,
        Round {
            previous,
            refactor: options.refactor,
            warm: options.warm,
            phases: options.phases,
            split_dual: options.split_dual,
        },
        comm.clone(),
        observer,
    )?;
    let mut rounds = 0;
    loop {
        let tolerance = scene.solver.tolerance;
        let found = unheld(scene, &state.problem, design, &state.u, tolerance);
        if found.unheld.is_empty() {
            state.search = Search { rounds, widened };
            state.times.total = t0.elapsed().as_secs_f64();
            return Ok(state);
        }
        let fixed = widen(&state.problem.searches, &found, &mut widened);
        let stuck = match fixed {
            Err(node) => Some((node, true)),
            Ok(()) if rounds >= max_rounds => deepest(&found.unheld).map(|u| (u, false)),
            Ok(()) => None,
        };
        if let Some((node, off_face)) = stuck {
            return Err(refusal(scene, &state, &node, rounds, off_face));
        }
        rounds += 1;
        let earlier = state;
        state = solve_on(
            &widened_scene(scene, &widened),
            design,
            Round {
                previous: Some(&earlier),
                refactor: Refactor::Changed,
                warm: WarmStart::OFF,
                phases: options.phases,
                split_dual: options.split_dual,
            },
            comm.clone(),
            observer,
        )?;
        add_cost(&mut state, &earlier);
    }
}

/// Widens the search of every contact with a node in `found` so that each
/// such node gets a row: to [`MARGIN`] times the larger of the contact's reach
/// (how far its bodies moved) and the nodes' deepest initial |gap|. Err: the
/// deepest node that no search distance holds (its projection falls beyond
/// the primary face at the start).
fn widen(
    searches: &[f64],
    found: &SearchFindings,
    widened: &mut [Option<f64>],
) -> Result<(), Unheld> {
    let off: Vec<Unheld> = found
        .unheld
        .iter()
        .filter(|u| {
            // A gap within the search with no row: no wider search helps.
            let search = searches.get(u.contact).copied().unwrap_or(f64::INFINITY);
            u.gap.is_none_or(|g| g.abs() <= search)
        })
        .copied()
        .collect();
    if let Some(u) = deepest(&off) {
        return Err(u);
    }
    for u in &found.unheld {
        let (c, gap) = (u.contact, u.gap.unwrap_or(0.0).abs());
        let reach = found.reach.get(c).copied().unwrap_or(0.0);
        let now = searches.get(c).copied().unwrap_or(0.0);
        let wider = (MARGIN * reach.max(gap)).max(now);
        if let Some(w) = widened.get_mut(c) {
            *w = Some(w.map_or(wider, |old| old.max(wider)));
        }
    }
    Ok(())
}

/// The node that ends deepest inside.
fn deepest(nodes: &[Unheld]) -> Option<Unheld> {
    nodes
        .iter()
        .copied()
        .max_by(|a, b| a.depth.total_cmp(&b.depth))
}

/// The refusal naming `node`, its contact and the last search distance.
fn refusal(
    scene: &Scene,
    state: &State,
    node: &Unheld,
    rounds: usize,
    off_face: bool,
) -> SolveError {
    let dim = state.problem.dim;
    SolveError::SearchUnsettled {
        contact: scene
            .contacts
            .get(node.contact)
            .map_or_else(String::new, |c| c.name.clone()),
        at: node.at[..dim].to_vec(),
        depth: node.depth,
        search: state
            .problem
            .searches
            .get(node.contact)
            .copied()
            .unwrap_or(0.0),
        rounds,
        off_face,
    }
}

/// `scene` with the search distances the loop set; only `search` differs, so
/// every name a report shows is the user's.
fn widened_scene<'a>(scene: &'a Scene, widened: &[Option<f64>]) -> Cow<'a, Scene> {
    if widened.iter().all(Option::is_none) {
        return Cow::Borrowed(scene);
    }
    let mut s = scene.clone();
    for (c, w) in s.contacts.iter_mut().zip(widened) {
        if let Some(w) = *w {
            c.search = Some(c.search.map_or(w, |own| own.max(w)));
        }
    }
    Cow::Owned(s)
}

/// Adds the cost of the solve a later round replaced (`earlier`, with its own
/// predecessors') to `state`, and keeps its factorization counts: the later
/// round reused its factorizations whole.
fn add_cost(state: &mut State, earlier: &State) {
    let (t, e) = (&mut state.times, &earlier.times);
    t.lower += e.lower;
    t.factorize += e.factorize;
    t.coarse += e.coarse;
    t.solve += e.solve;
    t.reconstruct += e.reconstruct;
    state.info.hessian_applications += earlier.info.hessian_applications;
    state.f_applications += earlier.f_applications;
    state.factorizations = earlier.factorizations;
    // Every round's predicted active set counted, the last one's outcome.
    if let (Some(p), Some(e)) = (state.prediction.as_mut(), &earlier.prediction) {
        p.smalbe_applications += e.smalbe_applications;
        p.equality_solves += e.equality_solves;
    }
}
