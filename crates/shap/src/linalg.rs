//! The small dense solve of Kernel SHAP's normal equations (`M − 1` unknowns, one
//! right-hand side per model output), in f64.

/// Solves `A · X = B` for symmetric positive semi-definite `A` (`[n, n]`) and `B`
/// (`[n, r]`), returning `X` (`[n, r]`). Cholesky when `A` is positive definite; otherwise
/// (too few coalitions for the features) the Moore–Penrose pseudo-inverse from a Jacobi
/// eigen-decomposition, as shap falls back to `pinv`.
pub(crate) fn solve_symmetric(a: &[f64], b: &[f64], n: usize, r: usize) -> Vec<f64> {
    cholesky_solve(a, b, n, r).unwrap_or_else(|| pinv_solve(a, b, n, r))
}

fn cholesky_solve(a: &[f64], b: &[f64], n: usize, r: usize) -> Option<Vec<f64>> {
    let scale = (0..n).map(|i| a[i * n + i].abs()).fold(0.0, f64::max);
    let mut l = vec![0f64; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                // Relative pivot threshold: a (numerically) singular system goes to pinv.
                if s <= 1e-13 * scale.max(f64::MIN_POSITIVE) {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    let mut x = b.to_vec();
    for c in 0..r {
        // Forward: L y = b.
        for i in 0..n {
            let mut s = x[i * r + c];
            for k in 0..i {
                s -= l[i * n + k] * x[k * r + c];
            }
            x[i * r + c] = s / l[i * n + i];
        }
        // Backward: Lᵀ x = y.
        for i in (0..n).rev() {
            let mut s = x[i * r + c];
            for k in i + 1..n {
                s -= l[k * n + i] * x[k * r + c];
            }
            x[i * r + c] = s / l[i * n + i];
        }
    }
    Some(x)
}

/// `A⁺ B` with `A = V Λ Vᵀ` from cyclic Jacobi rotations; eigenvalues below
/// `1e-12 · max|λ|` count as zero.
fn pinv_solve(a: &[f64], b: &[f64], n: usize, r: usize) -> Vec<f64> {
    let mut m = a.to_vec();
    let mut v = vec![0f64; n * n];
    (0..n).for_each(|i| v[i * n + i] = 1.0);
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i * n + j] * m[i * n + j])
            .sum();
        let diag: f64 = (0..n).map(|i| m[i * n + i] * m[i * n + i]).sum();
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = m[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (m[q * n + q] - m[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (mkp, mkq) = (m[k * n + p], m[k * n + q]);
                    m[k * n + p] = c * mkp - s * mkq;
                    m[k * n + q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let (mpk, mqk) = (m[p * n + k], m[q * n + k]);
                    m[p * n + k] = c * mpk - s * mqk;
                    m[q * n + k] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let lambda: Vec<f64> = (0..n).map(|i| m[i * n + i]).collect();
    let top = lambda.iter().fold(0f64, |acc, l| acc.max(l.abs()));
    let mut x = vec![0f64; n * r];
    for e in 0..n {
        if lambda[e].abs() <= 1e-12 * top || top == 0.0 {
            continue;
        }
        for c in 0..r {
            // (vₑᵀ b) / λₑ · vₑ
            let proj: f64 = (0..n).map(|i| v[i * n + e] * b[i * r + c]).sum::<f64>() / lambda[e];
            for i in 0..n {
                x[i * r + c] += proj * v[i * n + e];
            }
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_and_pinv_agree_on_a_regular_system() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let b = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let x1 = cholesky_solve(&a, &b, 3, 2).unwrap();
        let x2 = pinv_solve(&a, &b, 3, 2);
        for (p, q) in x1.iter().zip(&x2) {
            assert!((p - q).abs() < 1e-12, "{p} {q}");
        }
        // A x = b
        for c in 0..2 {
            for i in 0..3 {
                let s: f64 = (0..3).map(|k| a[i * 3 + k] * x1[k * 2 + c]).sum();
                assert!((s - b[i * 2 + c]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn singular_system_gets_the_minimum_norm_solution() {
        // Rank one: [[1, 1], [1, 1]] x = [2, 2] → x = [1, 1].
        let x = solve_symmetric(&[1.0, 1.0, 1.0, 1.0], &[2.0, 2.0], 2, 1);
        assert!(
            (x[0] - 1.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12,
            "{x:?}"
        );
    }
}
