//! Tick steps and labels shared by the figures' axes.

/// A "nice" tick step (1, 2 or 5 × 10ⁿ) giving about `n` ticks over `span`.
pub(crate) fn nice_step(span: f64, n: f64) -> f64 {
    let raw = span / n;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// Tick label for `v` when ticks are about `step` apart: plain decimals for ordinary
/// magnitudes, scientific notation for very small or large ones.
pub(crate) fn tick_label(v: f64, step: f64) -> String {
    if v.abs() < step.abs() * 1e-6 || v == 0.0 {
        return "0".into();
    }
    let step_exp = step.abs().log10().floor();
    let mag = v.abs().max(step.abs());
    if mag >= 1e5 || step_exp < -4.0 {
        let digits = (mag.log10().floor() - step_exp).clamp(0.0, 6.0) as usize;
        format!("{v:.digits$e}")
    } else {
        let decimals = (-step_exp).max(0.0) as usize;
        format!("{v:.decimals$}")
    }
}
