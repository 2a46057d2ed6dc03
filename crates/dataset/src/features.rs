//! Feature names and groups of each experiment's state and action vectors.

use crate::Experiment;

/// Consecutive state features predicted by one forward-model head and reported as one
/// MAE figure (θ, ef, object position, …).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FeatureGroup {
    /// Head / metric name.
    pub name: &'static str,
    /// First feature index in s.
    pub start: usize,
    /// Number of features.
    pub len: usize,
    /// Unit of the MAE.
    pub unit: &'static str,
    /// Euler angles: errors are wrapped into (−π, π] before averaging.
    pub angular: bool,
}

const fn group(
    name: &'static str,
    start: usize,
    len: usize,
    unit: &'static str,
    angular: bool,
) -> FeatureGroup {
    FeatureGroup {
        name,
        start,
        len,
        unit,
        angular,
    }
}

/// State sub-vectors of `experiment`, in state order.
pub fn state_groups(experiment: Experiment) -> Vec<FeatureGroup> {
    match experiment {
        Experiment::Exp1 => vec![
            group("theta", 0, 7, "rad", false),
            group("ef", 7, 3, "m", false),
        ],
        Experiment::Exp2 => vec![
            group("obj_pos", 0, 3, "m", false),
            group("obj_rot", 3, 3, "rad", true),
            group("colour", 6, 3, "", false),
            group("theta", 9, 7, "rad", false),
            group("ef_pos", 16, 3, "m", false),
            group("ef_rot", 19, 3, "rad", true),
            group("magnet", 22, 1, "", false),
        ],
    }
}

/// Names of s's features (the paper's symbols in ASCII).
pub fn state_names(experiment: Experiment) -> Vec<String> {
    let theta = (0..7).map(|i| format!("theta{i}"));
    match experiment {
        Experiment::Exp1 => theta
            .chain(["ef_x", "ef_y", "ef_z"].map(String::from))
            .collect(),
        Experiment::Exp2 => [
            "o_x", "o_y", "o_z", "o_rx", "o_ry", "o_rz", "o_R", "o_G", "o_B",
        ]
        .map(String::from)
        .into_iter()
        .chain(theta)
        .chain(["ef_x", "ef_y", "ef_z", "ef_rx", "ef_ry", "ef_rz", "mgt"].map(String::from))
        .collect(),
    }
}

/// Which state features are Euler angles (their differences are wrapped), in state order.
pub fn angular_features(experiment: Experiment) -> Vec<bool> {
    let mut angular = vec![false; state_width(experiment)];
    for g in state_groups(experiment) {
        angular[g.start..g.start + g.len].fill(g.angular);
    }
    angular
}

/// Number of state features, without building the names.
pub const fn state_width(experiment: Experiment) -> usize {
    match experiment {
        Experiment::Exp1 => 10,
        Experiment::Exp2 => 23,
    }
}

/// Number of action features, without building the names.
pub const fn action_width(experiment: Experiment) -> usize {
    match experiment {
        Experiment::Exp1 => 7,
        Experiment::Exp2 => 8,
    }
}

/// Names of a's features: `a0..a6` joint deltas, and `a_mgt` (−1 off, 0 keep, +1 on) in exp 2.
pub fn action_names(experiment: Experiment) -> Vec<String> {
    let deltas = (0..7).map(|i| format!("a{i}"));
    match experiment {
        Experiment::Exp1 => deltas.collect(),
        Experiment::Exp2 => deltas.chain(std::iter::once("a_mgt".to_owned())).collect(),
    }
}

/// An angle difference mapped into (−π, π], so Euler-angle errors near ±π are not 2π.
pub fn wrap_angle(delta: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let wrapped = delta - tau * (delta / tau).round();
    if wrapped <= -std::f64::consts::PI {
        wrapped + tau
    } else {
        wrapped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_the_state_exactly() {
        for exp in [Experiment::Exp1, Experiment::Exp2] {
            let groups = state_groups(exp);
            let mut next = 0;
            for g in &groups {
                assert_eq!(g.start, next, "{exp} group {}", g.name);
                next += g.len;
            }
            assert_eq!(next, state_names(exp).len());
        }
        assert_eq!(state_names(Experiment::Exp2).len(), 23);
        assert_eq!(action_names(Experiment::Exp2).len(), 8);
        assert_eq!(state_names(Experiment::Exp1).len(), 10);
        assert_eq!(state_names(Experiment::Exp2)[9], "theta0");
        for exp in [Experiment::Exp1, Experiment::Exp2] {
            assert_eq!(state_width(exp), state_names(exp).len());
            assert_eq!(action_width(exp), action_names(exp).len());
        }
    }

    #[test]
    fn wrapped_angles_stay_in_range() {
        use std::f64::consts::PI;
        assert!((wrap_angle(2.0 * PI - 0.1) + 0.1).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.3) - 0.3).abs() < 1e-12);
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * PI)).abs() < 1e-12);
    }
}
