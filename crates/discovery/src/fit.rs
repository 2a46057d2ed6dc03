//! The fit behind every test: least squares of each change on the design, then each
//! action block's Wald (robust) or F (classical) test, as tail probabilities and deviates.

use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor, Normal};

use crate::design::Design;

/// Residual sums of squares below this share of the change's total are rounding (the
/// classical F test's floor).
const RESIDUAL_FLOOR: f64 = 1e-12;

/// The largest deviate reported (an exactly fitted effect's statistic is infinite; claims
/// files hold finite numbers).
const MAX_DEVIATE: f64 = 1e6;

/// The test of one action on one feature's change.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PairTest {
    /// Wald χ² (robust) or F statistic of the block.
    pub statistic: f64,
    /// Columns in the block (0: the action never varied).
    pub dof: usize,
    /// Tail probability of the statistic under "no effect".
    pub p_value: f64,
    /// The tail probability as a standard-normal deviate (Wilson–Hilferty's approximation
    /// where it underflows), comparable across blocks of different sizes: the raw score
    /// for rankings.
    pub z: f64,
    /// Std over the rows of the block's fitted contribution to Δs_k (feature units).
    pub effect: f64,
    /// RMS residual of Δs_k fitted without a_j's block (feature units).
    pub rms_without: f64,
}

/// Rows grouped by cluster: per row its cluster's index (0..count), and the count.
pub(crate) struct ClusterIndex {
    of_row: Vec<usize>,
    count: usize,
}

pub(crate) fn cluster_index(ids: &[u64]) -> ClusterIndex {
    let mut seen = std::collections::HashMap::new();
    let of_row = ids
        .iter()
        .map(|id| {
            let next = seen.len();
            *seen.entry(*id).or_insert(next)
        })
        .collect();
    ClusterIndex {
        of_row,
        count: seen.len(),
    }
}

/// The robust covariance of a block's coefficients from its scores `g` (rows: the bread's
/// block columns times the residual): HC1 for independent rows, or CR1 (scores summed
/// within each cluster, small-sample factor G/(G−1) · (n−1)/(n−p)) for correlated ones.
fn robust_covariance(g: DMatrix<f64>, clusters: Option<&ClusterIndex>, p: usize) -> DMatrix<f64> {
    let n = g.nrows();
    let dof_resid = n.saturating_sub(p).max(1) as f64;
    match clusters {
        None => g.tr_mul(&g) * (n as f64 / dof_resid),
        Some(c) => {
            let mut sums = DMatrix::zeros(c.count, g.ncols());
            for (r, &k) in c.of_row.iter().enumerate() {
                let mut row = sums.row_mut(k);
                row += g.row(r);
            }
            let groups = c.count.max(2) as f64;
            sums.tr_mul(&sums) * (groups / (groups - 1.0) * (n as f64 - 1.0) / dof_resid)
        }
    }
}

/// Least squares of every column of `y` on the design, then every pair's block test.
pub(crate) fn fit_and_test(
    design: &Design,
    y: &DMatrix<f64>,
    robust: bool,
    clusters: Option<&ClusterIndex>,
) -> Vec<Vec<PairTest>> {
    let x = &design.x;
    let (n, p) = x.shape();
    let gram = x.tr_mul(x);
    // The design's columns are independent (see `Design::build`), so the Gram matrix is
    // positive definite; the pseudo-inverse is only a guard against rounding.
    let inverse = match gram.clone().cholesky() {
        Some(c) => c.inverse(),
        None => {
            let tolerance = 1e-10 * gram.diagonal().max();
            gram.pseudo_inverse(tolerance)
                .expect("a non-negative tolerance is accepted")
        }
    };
    let beta = &inverse * x.tr_mul(y);
    let residual = y - x * &beta;
    let rss: Vec<f64> = residual.column_iter().map(|e| e.norm_squared()).collect();
    // The F test's noise floor: a residual below 1e-12 of the change's own variance is f32
    // rounding (θ_j + a_j recorded in f32), not noise an action could be tested against;
    // without the floor the classical test reads rounding as effects.
    let rss_floor: Vec<f64> = y
        .column_iter()
        .zip(&rss)
        .map(|(c, &r)| {
            let mean = c.mean();
            r.max(RESIDUAL_FLOOR * c.iter().map(|v| (v - mean).powi(2)).sum::<f64>())
        })
        .collect();
    // Rows of X (XᵀX)⁻¹: the sandwich's bread applied to each row, for the robust test.
    let bread = robust.then(|| x * &inverse);
    let dof_resid = (n - p).max(1) as f64;
    design
        .blocks
        .iter()
        .map(|&(start, m)| {
            (0..y.ncols())
                .map(|k| {
                    if m == 0 {
                        return PairTest::untested(rss[k], n);
                    }
                    let b = beta.view((start, k), (m, 1)).into_owned();
                    let cov_unscaled = inverse.view((start, start), (m, m)).into_owned();
                    let drop_rss = quadratic_form(&b, &cov_unscaled);
                    let (statistic, p_value, z) = match &bread {
                        Some(bread) => {
                            let h = bread.columns(start, m);
                            let e = residual.column(k);
                            let g = DMatrix::from_fn(n, m, |r, c| h[(r, c)] * e[r]);
                            let v = robust_covariance(g, clusters, p);
                            let w = quadratic_form(&b, &v);
                            let p = chi2_tail(w, m);
                            (w, p, deviate(p, wilson_hilferty(w, m)))
                        }
                        None => {
                            let f = drop_rss
                                / m as f64
                                / (rss_floor[k] / dof_resid).max(f64::MIN_POSITIVE);
                            let p = f_tail(f, m, dof_resid);
                            (f, p, deviate(p, wilson_hilferty(f * m as f64, m)))
                        }
                    };
                    let fitted = x.columns(start, m) * &b;
                    PairTest {
                        statistic,
                        dof: m,
                        p_value,
                        z,
                        effect: std_dev(fitted.as_slice()),
                        rms_without: ((rss[k] + drop_rss.max(0.0)) / n as f64).sqrt(),
                    }
                })
                .collect()
        })
        .collect()
}

impl PairTest {
    /// The pair of an action that never varied: nothing tested.
    pub(crate) fn untested(rss: f64, n: usize) -> Self {
        Self {
            statistic: 0.0,
            dof: 0,
            p_value: 1.0,
            z: f64::NEG_INFINITY.max(-40.0),
            effect: 0.0,
            rms_without: (rss / n.max(1) as f64).sqrt(),
        }
    }
}

/// bᵀ M⁻¹ b with M's pseudo-inverse (a block may be rank-deficient). A zero M (a change
/// fitted exactly, so the robust covariance vanishes) gives ∞ for a nonzero b, 0 for b = 0.
fn quadratic_form(b: &DMatrix<f64>, m: &DMatrix<f64>) -> f64 {
    let scale = m.diagonal().iter().fold(0.0f64, |a, &v| a.max(v.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return if b.iter().any(|&v| v != 0.0) {
            f64::INFINITY
        } else {
            0.0
        };
    }
    let Ok(inv) = m.clone().pseudo_inverse(1e-12 * scale) else {
        return 0.0;
    };
    let v: DVector<f64> = b.column(0).into_owned();
    v.dot(&(inv * &v))
}

fn chi2_tail(w: f64, dof: usize) -> f64 {
    ChiSquared::new(dof as f64).map_or(1.0, |d| d.sf(w.max(0.0)))
}

fn f_tail(f: f64, dof: usize, dof_resid: f64) -> f64 {
    FisherSnedecor::new(dof as f64, dof_resid).map_or(1.0, |d| d.sf(f.max(0.0)))
}

/// The standard-normal deviate of tail probability `p` (so z ≥ the critical z exactly
/// where p ≤ the level); where p underflows to 0, `approximate` (at least the deviate of the
/// smallest positive p), so rankings keep their order among very strong edges.
fn deviate(p: f64, approximate: f64) -> f64 {
    let normal = Normal::standard();
    if p >= f64::MIN_POSITIVE {
        (-normal.inverse_cdf(p)).clamp(-40.0, 40.0)
    } else {
        approximate.max(-normal.inverse_cdf(f64::MIN_POSITIVE))
    }
}

/// A χ²(dof) statistic as a standard-normal deviate (Wilson–Hilferty): the ranking of
/// statistics whose tail probability underflows.
fn wilson_hilferty(w: f64, dof: usize) -> f64 {
    let k = dof as f64;
    let c = 2.0 / (9.0 * k);
    (((w.max(0.0) / k).cbrt() - (1.0 - c)) / c.sqrt()).clamp(-40.0, MAX_DEVIATE)
}

fn std_dev(values: &[f64]) -> f64 {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}
