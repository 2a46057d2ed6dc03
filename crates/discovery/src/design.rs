//! Regressors of the tests: an intercept and the standardized state (the controls), then one
//! block of columns per action whose joint coefficient the test asks about.

use nalgebra::DMatrix;

use crate::Changes;

/// Columns whose part outside the span of the columns before them is below this fraction
/// of their norm (squared) are dropped: a discrete command makes some terms exact
/// combinations of others (the magnet's a², a × mgt and a), and least squares on such
/// columns turns rounding into effects.
const DEPENDENCE_TOLERANCE: f64 = 1e-9;

/// Which terms of a_j make up its block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Terms {
    /// a_j alone: plain linear Granger.
    Linear,
    /// a_j and a_j × s_i for every state feature: a gain that depends on the state (a joint
    /// moves the tool by the Jacobian of the pose it is in).
    Interaction,
    /// As `Interaction`, and a_j²: effects of either sign of a_j alike, and the three
    /// levels of a discrete command (the magnet's −1, 0, +1); and hinges max(0, a_j − q) at
    /// [`HINGE_QUANTILES`] of a_j: a response that saturates, as a velocity-limited joint
    /// moves at most its limit × dt however far the command reaches (the dynamic arm's
    /// joint 6: 0.87 × the command, flat beyond 0.098 rad). Without them the own joint's
    /// misfit leaks into the blocks of the actions the scripted phases move along with it:
    /// on a 50,000-step dynamic-arm bag every a_i → θ6 (i < 6) was claimed at z = 8–19,
    /// against a truth of no effect.
    Full,
}

/// Quantiles of an action at which [`Terms::Full`] puts its hinges.
pub const HINGE_QUANTILES: [f64; 4] = [0.05, 0.2, 0.8, 0.95];

/// The design matrix and where each action's block lies in it.
pub(crate) struct Design {
    /// `[row][column]`, every column but the intercept standardized.
    pub(crate) x: DMatrix<f64>,
    /// Per action: first column and column count of its block.
    pub(crate) blocks: Vec<(usize, usize)>,
}

/// Column `values` centred and scaled to unit std, or `None` when it is constant.
fn standardized(values: Vec<f64>) -> Option<Vec<f64>> {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    // A column constant to rounding (relative spread below 1e-12) carries no information.
    if var.sqrt() <= 1e-12 * mean.abs().max(f64::MIN_POSITIVE) || var == 0.0 {
        return None;
    }
    let sd = var.sqrt();
    Some(values.into_iter().map(|v| (v - mean) / sd).collect())
}

impl Design {
    /// The design of `terms` on `changes`: intercept, the non-constant state features, then
    /// per action its block (a constant action gets an empty block).
    pub(crate) fn build(changes: &Changes, terms: Terms) -> Self {
        let n = changes.rows.len();
        let na = changes.actions.first().map_or(0, Vec::len);
        let state = state_controls(changes);
        let mut columns: Vec<Vec<f64>> = vec![vec![1.0; n]];
        columns.extend(state.iter().cloned());
        let mut blocks = Vec::with_capacity(na);
        for j in 0..na {
            let start = columns.len();
            if let Some(a) = standardized(changes.actions.iter().map(|a| a[j]).collect()) {
                let mut block = Vec::new();
                if terms == Terms::Full {
                    block.extend(standardized(a.iter().map(|v| v * v).collect()));
                    block.extend(hinges(&a).into_iter().filter_map(standardized));
                }
                if terms != Terms::Linear {
                    for z in &state {
                        block.extend(standardized(a.iter().zip(z).map(|(a, z)| a * z).collect()));
                    }
                }
                columns.push(a);
                columns.extend(block);
            }
            blocks.push((start, columns.len() - start));
        }
        let all = DMatrix::from_fn(n, columns.len(), |r, c| columns[c][r]);
        drop(columns);
        let kept = independent_columns(&all.tr_mul(&all));
        let mut index = vec![usize::MAX; all.ncols()];
        for (new, &old) in kept.iter().enumerate() {
            index[old] = new;
        }
        let blocks = blocks
            .into_iter()
            .map(|(start, len)| {
                let cols: Vec<usize> = (start..start + len)
                    .map(|c| index[c])
                    .filter(|&c| c != usize::MAX)
                    .collect();
                (cols.first().copied().unwrap_or(0), cols.len())
            })
            .collect();
        let x = all.select_columns(&kept);
        Self { x, blocks }
    }
}

/// The hinge columns max(0, a − q) of action column `a` at its [`HINGE_QUANTILES`] (one
/// per distinct knot; a discrete command's hinges repeat its levels and are dropped as
/// dependent).
fn hinges(a: &[f64]) -> Vec<Vec<f64>> {
    let mut sorted = a.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut knots: Vec<f64> = HINGE_QUANTILES
        .iter()
        .filter_map(|q| sorted.get(((sorted.len().max(1) - 1) as f64 * q) as usize))
        .copied()
        .collect();
    knots.dedup();
    knots
        .into_iter()
        .map(|knot| a.iter().map(|v| (v - knot).max(0.0)).collect())
        .collect()
}

/// The state as controls and interaction partners, standardized: a plain feature as it is,
/// an Euler angle as its sine and cosine (its value jumps by 2π at ±π, its pose does not),
/// and whether the cube is held (where it varies).
fn state_controls(changes: &Changes) -> Vec<Vec<f64>> {
    let ns = changes.states.first().map_or(0, Vec::len);
    let column = |k: usize, f: fn(f64) -> f64| changes.states.iter().map(|s| f(s[k])).collect();
    let mut controls = Vec::new();
    for k in 0..ns {
        if changes.angular[k] {
            controls.extend(standardized(column(k, f64::sin)));
            controls.extend(standardized(column(k, f64::cos)));
        } else {
            controls.extend(standardized(column(k, |v| v)));
        }
    }
    controls.extend(standardized(changes.holding.clone()));
    controls
}

/// Indices of the columns kept, in order: each column whose part outside the span of the
/// kept ones before it is not negligible, from an incremental Cholesky factor of the Gram
/// matrix `gram`. Blocks stay contiguous because whole columns are only ever dropped.
fn independent_columns(gram: &DMatrix<f64>) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    // Rows of the lower-triangular factor L of the kept columns' Gram matrix.
    let mut factor: Vec<Vec<f64>> = Vec::new();
    for j in 0..gram.ncols() {
        let norm = gram[(j, j)];
        if norm <= 0.0 {
            continue;
        }
        // Solve L y = (Gram entries of the kept columns with column j).
        let mut y: Vec<f64> = Vec::with_capacity(kept.len() + 1);
        for (i, &c) in kept.iter().enumerate() {
            let s: f64 = (0..i).map(|m| factor[i][m] * y[m]).sum();
            y.push((gram[(c, j)] - s) / factor[i][i]);
        }
        let rest = norm - y.iter().map(|v| v * v).sum::<f64>();
        if rest > DEPENDENCE_TOLERANCE * norm {
            y.push(rest.sqrt());
            factor.push(y);
            kept.push(j);
        }
    }
    kept
}
