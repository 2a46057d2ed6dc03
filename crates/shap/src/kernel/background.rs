//! The weighted background that stands in for "feature unknown", and its k-means summary.

use rand::{Rng, SeedableRng, rngs::StdRng};
use rayon::prelude::*;

use super::draw_weighted;
use crate::{Result, ShapError, check_rows};

/// Weighted background rows that stand in for "feature unknown" (replaced features take
/// their values from these rows, weighted).
#[derive(Debug, Clone, PartialEq)]
pub struct Background {
    data: Vec<f32>,
    weights: Vec<f64>,
    width: usize,
}

impl Background {
    /// Rows with equal weights (a plain sample of the data).
    pub fn sample(data: &[f32], width: usize) -> Result<Self> {
        let rows = check_rows("background", data, width)?;
        Self::weighted(data, width, vec![1.0; rows])
    }

    /// Rows with the given non-negative weights (normalised to sum 1).
    pub fn weighted(data: &[f32], width: usize, weights: Vec<f64>) -> Result<Self> {
        let rows = check_rows("background", data, width)?;
        if weights.len() != rows {
            return Err(ShapError::Shape(format!(
                "{} weights for {rows} background rows",
                weights.len()
            )));
        }
        if weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(ShapError::NonFinite(
                "background weights must be finite and non-negative".into(),
            ));
        }
        let total: f64 = weights.iter().sum();
        if total <= 0.0 {
            return Err(ShapError::Empty("background weights sum to 0".into()));
        }
        Ok(Self {
            data: data.to_vec(),
            weights: weights.iter().map(|w| w / total).collect(),
            width,
        })
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.weights.len()
    }

    /// Row width (model inputs).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Row-major rows `[rows, width]`.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Weights, summing to 1.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }
}

/// Summarises `data` (`[rows, width]`) by `k` weighted k-means centres, as `shap.kmeans`:
/// k-means++ seeding (best of 3 runs of Lloyd's algorithm, seeded), then every centre
/// coordinate is snapped to the nearest value that column takes in the data (so
/// categorical or discrete features stay valid) and weighted by its cluster's size.
/// With `k ≥ rows` the data itself is returned with equal weights. Each iteration costs
/// `rows · k · width` (the assignment runs on rayon's global pool): subsample very large
/// data sets first.
pub fn kmeans(data: &[f32], width: usize, k: usize, seed: u64) -> Result<Background> {
    let n = check_rows("k-means data", data, width)?;
    if k == 0 {
        return Err(ShapError::Option("k-means needs k ≥ 1".into()));
    }
    if k >= n {
        return Background::sample(data, width);
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let clustering = Clustering { data, width, n, k };
    let mut best: Option<(f64, Vec<f64>, Vec<usize>)> = None;
    for _ in 0..3 {
        let mut centres = clustering.seed_centres(&mut rng);
        let (inertia, labels) = clustering.lloyd(&mut centres);
        if best.as_ref().is_none_or(|b| inertia < b.0) {
            best = Some((inertia, centres, labels));
        }
    }
    let (_, centres, labels) = best.expect("three runs were made");
    clustering.snap_to_column_values(&centres, &labels)
}

/// The data and cluster count every k-means step reads, so the steps share one context
/// instead of passing the same four values around. Centres are row-major `[k, width]` f64.
struct Clustering<'a> {
    data: &'a [f32],
    width: usize,
    /// Number of data rows.
    n: usize,
    /// Number of clusters (`1 ≤ k < n`).
    k: usize,
}

impl Clustering<'_> {
    /// Row `i` of the data; one place for the row-major indexing.
    fn row(&self, i: usize) -> &[f32] {
        &self.data[i * self.width..(i + 1) * self.width]
    }

    /// Centre `c` of `centres`; one place for the row-major indexing.
    fn centre<'c>(&self, centres: &'c [f64], c: usize) -> &'c [f64] {
        &centres[c * self.width..(c + 1) * self.width]
    }

    /// k-means++ seeding: spread initial centres apart (each next centre drawn with
    /// probability ∝ squared distance to the nearest one so far), which makes Lloyd's
    /// algorithm converge faster and to better optima than uniform seeding.
    fn seed_centres(&self, rng: &mut StdRng) -> Vec<f64> {
        let (n, k, width) = (self.n, self.k, self.width);
        let mut centres: Vec<f64> = Vec::with_capacity(k * width);
        let first = rng.random_range(0..n);
        centres.extend(self.row(first).iter().map(|&v| f64::from(v)));
        let mut d2: Vec<f64> = (0..n)
            .map(|i| squared_distance(self.row(i), &centres[..width]))
            .collect();
        for c in 1..k {
            let total: f64 = d2.iter().sum();
            let pick = if total > 0.0 {
                draw_weighted(&d2, total, rng)
            } else {
                rng.random_range(0..n)
            };
            centres.extend(self.row(pick).iter().map(|&v| f64::from(v)));
            let centre = self.centre(&centres, c);
            for (i, d) in d2.iter_mut().enumerate() {
                *d = d.min(squared_distance(self.row(i), centre));
            }
        }
        centres
    }

    /// Lloyd iterations from the seeded `centres` (updated in place) until no label
    /// changes (at most 300); returns the inertia of the last assignment, by which the
    /// best of several seeded runs is chosen, and the labels.
    fn lloyd(&self, centres: &mut [f64]) -> (f64, Vec<usize>) {
        let mut labels = vec![usize::MAX; self.n];
        let mut inertia = 0.0;
        for _ in 0..300 {
            let mut changed = false;
            inertia = 0.0;
            for (label, &(bi, bd)) in labels.iter_mut().zip(&self.nearest_centres(centres)) {
                inertia += bd;
                if *label != bi {
                    *label = bi;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
            self.update_centres(centres, &labels);
        }
        (inertia, labels)
    }

    /// Nearest centre of every row and its squared distance, in parallel (per-row
    /// results, so the sums made from them do not depend on the thread split).
    fn nearest_centres(&self, centres: &[f64]) -> Vec<(usize, f64)> {
        (0..self.n)
            .into_par_iter()
            .map(|i| {
                let (mut bi, mut bd) = (0, f64::INFINITY);
                for c in 0..self.k {
                    let d = squared_distance(self.row(i), self.centre(centres, c));
                    if d < bd {
                        (bi, bd) = (c, d);
                    }
                }
                (bi, bd)
            })
            .collect()
    }

    /// Moves every centre to the mean of its rows; an empty cluster instead takes the
    /// row farthest from its own centre, so no centre is lost.
    fn update_centres(&self, centres: &mut [f64], labels: &[usize]) {
        let (n, k, width) = (self.n, self.k, self.width);
        let mut sum = vec![0f64; k * width];
        let mut count = vec![0usize; k];
        for (i, &l) in labels.iter().enumerate() {
            count[l] += 1;
            for (s, &v) in sum[l * width..(l + 1) * width].iter_mut().zip(self.row(i)) {
                *s += f64::from(v);
            }
        }
        for c in 0..k {
            if count[c] == 0 {
                // An empty cluster takes the point farthest from its centre.
                let far = (0..n)
                    .max_by(|&a, &b| {
                        let da = squared_distance(self.row(a), self.centre(centres, labels[a]));
                        let db = squared_distance(self.row(b), self.centre(centres, labels[b]));
                        da.total_cmp(&db)
                    })
                    .unwrap_or(0);
                for (dst, &v) in centres[c * width..(c + 1) * width]
                    .iter_mut()
                    .zip(self.row(far))
                {
                    *dst = f64::from(v);
                }
            } else {
                for (dst, s) in centres[c * width..(c + 1) * width]
                    .iter_mut()
                    .zip(&sum[c * width..(c + 1) * width])
                {
                    *dst = s / count[c] as f64;
                }
            }
        }
    }

    /// The weighted background of the clustering: each coordinate snapped to the nearest
    /// value of its column (first such row, as numpy's argmin) so discrete features stay
    /// valid, each centre weighted by its cluster's size, clusters that ended empty
    /// dropped.
    fn snap_to_column_values(&self, centres: &[f64], labels: &[usize]) -> Result<Background> {
        let (n, k, width) = (self.n, self.k, self.width);
        let mut weights = vec![0f64; k];
        labels.iter().for_each(|&l| weights[l] += 1.0);
        let mut out = Vec::with_capacity(k * width);
        let mut out_w = Vec::with_capacity(k);
        for c in 0..k {
            if weights[c] == 0.0 {
                continue;
            }
            for j in 0..width {
                let target = centres[c * width + j];
                let mut best = (f64::INFINITY, 0f32);
                for i in 0..n {
                    let v = self.data[i * width + j];
                    let d = (f64::from(v) - target).abs();
                    if d < best.0 {
                        best = (d, v);
                    }
                }
                out.push(best.1);
            }
            out_w.push(weights[c]);
        }
        Background::weighted(&out, width, out_w)
    }
}

/// Squared Euclidean distance of a data row to a centre, accumulated in f64 so centres
/// (means of many rows) are compared without f32 rounding.
fn squared_distance(a: &[f32], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &c)| (f64::from(x) - c).powi(2))
        .sum()
}
