//! The data test within each context of the state as well as over all rows, for the
//! intermittent features: those that stand still in much of the data.
//!
//! The cube moves only while the magnet holds it or as it falls: an effect on it (switching
//! the magnet off drops it; a joint turns it only while it is held) is averaged over every
//! row where the cube rests, and the change's variance elsewhere buries it. Within the
//! context the same design sees it. A feature that moves nearly everywhere (a joint, the
//! effector) is tested over all rows only: within the contexts of the scripted pick and
//! place the commands are a function of the phase, and the arm's hidden velocity
//! confounds them. Testing every feature within every context claimed 16 false edges on
//! the dynamic arm's 50,000-step bag (a_mgt → θ0 at p = 1e-77 within `holding`), against
//! 4 for the intermittent features alone.

use causal_arm_dataset::{Context, ContextReader, Dataset};
use rayon::prelude::*;

use crate::Changes;
use crate::design::Design;
use crate::fit::{PairTest, cluster_index, fit_and_test};
use crate::granger::GrangerSettings;

/// A feature is intermittent when it moves (changes by more than the data test's
/// resolution margin) in at most this share of the rows. On the dynamic arm's
/// 50,000-step bag the cube's features move in 56–58 % of the rows (held or falling),
/// the magnet's in 2 %, the joints in 96–99 % and the effector in 99.6–99.8 %.
pub const INTERMITTENT_SHARE: f64 = 0.75;

/// One context's tests of every pair.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ContextTest {
    /// The context's name ([`Context::of`]).
    pub context: String,
    /// Transitions of the draw that lie in the context.
    pub rows: usize,
    /// `[action][state]`, as over all rows; untested (no columns) for the features that
    /// are not intermittent.
    pub pairs: Vec<Vec<PairTest>>,
}

/// The drawn rows of each context of `data`'s experiment but `all`, by name.
fn context_members(changes: &Changes, data: &Dataset) -> Vec<(&'static str, Vec<usize>)> {
    let reader = ContextReader::new(data.experiment);
    Context::of(data.experiment)
        .iter()
        .filter(|context| context.name != Context::ALL)
        .map(|context| {
            let members = (0..changes.rows.len())
                .filter(|&i| reader.holds(data, changes.rows[i], context))
                .collect();
            (context.name, members)
        })
        .collect()
}

/// Per feature: whether it is intermittent ([`INTERMITTENT_SHARE`]), so that its
/// effects live in the contexts where it moves.
pub(crate) fn intermittent_features(changes: &Changes, margin: f64) -> Vec<bool> {
    let n = changes.rows.len() as f64;
    (0..changes.resolution.len())
        .map(|k| {
            let bound = margin * changes.resolution[k];
            let moving = changes.deltas.iter().filter(|d| d[k].abs() > bound).count();
            moving > 0 && moving as f64 <= INTERMITTENT_SHARE * n
        })
        .collect()
}

/// The tests of the `intermittent` features within every context of `data`'s experiment but
/// `all`, on the rows of `changes` whose s(t) lies in it. A context without rows, or with
/// fewer than twice the design's columns, is left out: its test could not be run.
pub(crate) fn tests_within_contexts(
    changes: &Changes,
    data: &Dataset,
    settings: &GrangerSettings,
    intermittent: &[bool],
) -> Vec<ContextTest> {
    let tested: Vec<usize> = (0..intermittent.len())
        .filter(|&k| intermittent[k])
        .collect();
    context_members(changes, data)
        .into_par_iter()
        .filter_map(|(name, members)| {
            let within = changes.subset(&members);
            let design = Design::build(&within, settings.terms);
            let (n, p) = design.x.shape();
            if n == 0 || n < 2 * p {
                return None;
            }
            let clusters = within.clusters.as_deref().map(cluster_index);
            let y = within.delta_matrix().select_columns(&tested);
            let fitted = fit_and_test(&design, &y, settings.robust, clusters.as_ref());
            let pairs = fitted
                .into_iter()
                .map(|row| {
                    let mut full = vec![PairTest::untested(0.0, n); intermittent.len()];
                    for (&k, t) in tested.iter().zip(row) {
                        full[k] = t;
                    }
                    full
                })
                .collect();
            Some(ContextTest {
                context: name.to_owned(),
                rows: n,
                pairs,
            })
        })
        .collect()
}
