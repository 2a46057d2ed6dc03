//! Physical statistics of a dataset: how far the joints were told to move and how far they
//! did, whether they kept their velocity limits, how deep the arm's links went into the
//! table, how often the cube lay on the floor, and how often switching the magnet on
//! caught the cube.
//!
//! They compare the simulator's arm modes (kinematic, dynamic) on their data, which the
//! learned models and the paper's figures then inherit. Every statistic is read from the
//! dataset's rows and the simulator's own link shapes, so both modes are judged alike.

use causal_arm_dataset::{Dataset, state_names};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::Experiment;
use causal_arm_protocol::{ARM_DOF, Scene};
use causal_arm_sim::{SimConfig, TableProbe};
use serde::Serialize;

/// Penetration above which a state counts as "in the table", m (contact slop is below it).
pub const PENETRATION_COUNTED: f64 = 1e-3;

/// A joint whose mean speed over a step exceeds its velocity limit by more than this
/// share counts as over its limit (the servo's rounding stays far below it).
pub const OVERSPEED_COUNTED: f64 = 0.01;

/// Why statistics could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum StatsError {
    /// The dataset lacks a feature the statistics read.
    #[error("the dataset has no state feature {0:?}")]
    MissingFeature(String),
    /// The table probe could not be built or placed.
    #[error(transparent)]
    Sim(#[from] causal_arm_sim::SimError),
    /// No rows to describe.
    #[error("the dataset has no transitions")]
    Empty,
}

/// The statistics of one dataset.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DataStats {
    /// Experiment of the rows.
    pub experiment: String,
    /// Transitions described.
    pub transitions: usize,
    /// Standard deviation of the commanded joint change a(t) = target − θ(t), per joint, rad.
    pub commanded_spread: [f64; ARM_DOF],
    /// Standard deviation of the realized joint change θ(t+1) − θ(t), per joint, rad.
    pub realized_spread: [f64; ARM_DOF],
    /// Realized ÷ commanded spread, mean over joints: how much of a command the arm did.
    pub realized_share: f64,
    /// Share of transitions in which some joint's mean speed exceeded its velocity limit
    /// (URDF × `velocity_scale`) by more than [`OVERSPEED_COUNTED`].
    pub overspeed_share: f64,
    /// Fastest mean speed of a joint over a step ÷ that joint's velocity limit.
    pub overspeed_max: f64,
    /// Where that was: the episode and step of the transition's first state.
    pub overspeed_max_at: [u32; 2],
    /// Share of recorded states (each transition's first, and each episode's last) with
    /// some link more than [`PENETRATION_COUNTED`] into the table.
    pub in_table_share: f64,
    /// Deepest any link went into the table, m.
    pub penetration_max: f64,
    /// Where that was: the state's episode and step in the data (first of equals).
    pub penetration_max_at: [u32; 2],
    /// 99.9th percentile of the penetration over states, m.
    pub penetration_p999: f64,
    /// Exp 2: share of states with the cube below the table top (fallen to the floor).
    pub cube_on_floor_share: Option<f64>,
    /// Exp 2: switch-ons of the magnet (a_mgt = +1 while off).
    pub switch_ons: Option<usize>,
    /// Exp 2: share of switch-ons after which the magnet held the cube before it was
    /// switched off again (or the episode ended).
    pub grasp_success: Option<f64>,
    /// Exp 2: why switch-ons missed, to compare arms by.
    pub grasp_misses: Option<GraspMisses>,
}

/// The switch-ons after which the magnet never held the cube.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GraspMisses {
    /// Switch-ons that missed.
    pub count: usize,
    /// Share of them with the cube on the floor at the switch-on (out of reach).
    pub cube_on_floor: f64,
    /// Of the misses with the cube on the table: quartiles of the closest the effector
    /// came to the cube's centre while the magnet was on, m (it catches within
    /// `capture_distance` of the cube's surface).
    pub closest_quartiles: [f64; 3],
    /// Of those: the median distance the cube moved while the magnet was on, m.
    pub cube_moved_median: f64,
}

/// Column of the state feature `name`.
fn feature(names: &[String], name: &str) -> Result<usize, StatsError> {
    names
        .iter()
        .position(|n| n == name)
        .ok_or_else(|| StatsError::MissingFeature(name.to_owned()))
}

/// Population standard deviation of `values`.
fn std_dev(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count().max(1) as f64;
    let mean = values.clone().sum::<f64>() / n;
    (values.map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The statistics of `data`, whose actions must be the commanded ones
/// (`ActionSource::Commanded`), in the scene of `config`.
pub fn describe(data: &Dataset, config: &SimConfig) -> Result<DataStats, StatsError> {
    let rows = data.rows();
    if rows == 0 {
        return Err(StatsError::Empty);
    }
    let names = state_names(data.experiment);
    let theta: Vec<usize> = (0..ARM_DOF)
        .map(|i| feature(&names, &format!("theta{i}")))
        .collect::<Result<_, _>>()?;
    let commanded_spread: [f64; ARM_DOF] =
        std::array::from_fn(|j| std_dev((0..rows).map(move |r| data.action(r)[j] as f64)));
    let realized_spread: [f64; ARM_DOF] = std::array::from_fn(|j| {
        let t = theta[j];
        std_dev((0..rows).map(move |r| (data.next_state(r)[t] - data.state(r)[t]) as f64))
    });
    let realized_share = (0..ARM_DOF)
        .map(|j| realized_spread[j] / commanded_spread[j].max(1e-12))
        .sum::<f64>()
        / ARM_DOF as f64;
    let (overspeed_share, overspeed_max, fastest_row) = overspeed(data, &theta, config);
    let (mut depths, places) = table_depths(data, &theta, config)?;
    let probed = depths.len();
    let in_table = depths.iter().filter(|&&d| d > PENETRATION_COUNTED).count();
    let deepest = (0..probed)
        .max_by(|&a, &b| depths[a].total_cmp(&depths[b]).then(b.cmp(&a)))
        .unwrap_or(0);
    let penetration_max = depths[deepest];
    let p999 = quantile(&mut depths, 0.999);
    let mut stats = DataStats {
        experiment: data.experiment.to_string(),
        transitions: rows,
        commanded_spread,
        realized_spread,
        realized_share,
        overspeed_share,
        overspeed_max,
        overspeed_max_at: [data.episodes[fastest_row], data.steps[fastest_row]],
        in_table_share: in_table as f64 / probed as f64,
        penetration_max,
        penetration_max_at: places[deepest],
        penetration_p999: p999,
        cube_on_floor_share: None,
        switch_ons: None,
        grasp_success: None,
        grasp_misses: None,
    };
    if data.experiment == Experiment::Exp2 {
        exp2_stats(data, &names, &config.scene(), &mut stats)?;
    }
    Ok(stats)
}

/// How deep the links reach into the table in every recorded state: each transition's
/// s(t), and the s(t+1) that ends each episode. With each depth, its [episode, step].
fn table_depths(
    data: &Dataset,
    theta: &[usize],
    config: &SimConfig,
) -> Result<(Vec<f64>, Vec<[u32; 2]>), StatsError> {
    let probe = TableProbe::new(config)?;
    let depth = |s: &[f32]| {
        let q: [f64; ARM_DOF] = std::array::from_fn(|j| s[theta[j]] as f64);
        probe.penetration(&q)
    };
    let rows = data.rows();
    let (mut depths, mut places) = (Vec::with_capacity(rows), Vec::with_capacity(rows));
    for r in 0..rows {
        let (episode, step) = (data.episodes[r], data.steps[r]);
        depths.push(depth(data.state(r))?);
        places.push([episode, step]);
        if data.episodes.get(r + 1) != Some(&episode) {
            depths.push(depth(data.next_state(r))?);
            places.push([episode, step + 1]);
        }
    }
    Ok((depths, places))
}

/// How often and how far the joints' mean speeds over a step exceeded their velocity
/// limits: (share of transitions with some joint over, largest speed ÷ limit, its row).
fn overspeed(data: &Dataset, theta: &[usize], config: &SimConfig) -> (f64, f64, usize) {
    let model = ArmModel::embedded();
    let step_seconds = config.dt * config.substeps as f64;
    let limit: Vec<f64> = model
        .limits()
        .iter()
        .map(|l| l.velocity * config.velocity_scale)
        .collect();
    let (mut over, mut fastest, mut fastest_row) = (0usize, 0.0f64, 0usize);
    for r in 0..data.rows() {
        let (s, next) = (data.state(r), data.next_state(r));
        let ratio = theta
            .iter()
            .zip(&limit)
            .map(|(&t, l)| ((next[t] - s[t]) as f64).abs() / step_seconds / l)
            .fold(0.0, f64::max);
        over += usize::from(ratio > 1.0 + OVERSPEED_COUNTED);
        if ratio > fastest {
            (fastest, fastest_row) = (ratio, r);
        }
    }
    (over as f64 / data.rows() as f64, fastest, fastest_row)
}

/// The cube and magnet statistics of an exp 2 dataset.
fn exp2_stats(
    data: &Dataset,
    names: &[String],
    scene: &Scene,
    stats: &mut DataStats,
) -> Result<(), StatsError> {
    let rows = data.rows();
    let o_z = feature(names, "o_z")?;
    let mgt = feature(names, "mgt")?;
    let on_floor = (0..rows)
        .filter(|&r| cube_on_floor(data.state(r)[o_z] as f64, scene))
        .count();
    stats.cube_on_floor_share = Some(on_floor as f64 / rows as f64);
    let magnet_action = ARM_DOF; // a_mgt follows the seven joint deltas
    let position = |prefix: &str| -> Result<[usize; 3], StatsError> {
        Ok([
            feature(names, &format!("{prefix}_x"))?,
            feature(names, &format!("{prefix}_y"))?,
            feature(names, &format!("{prefix}_z"))?,
        ])
    };
    let (ef, cube) = (position("ef")?, position("o")?);
    let at = |r: usize, f: [usize; 3]| f.map(|k| data.state(r)[k] as f64);
    let distance = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let (mut switch_ons, mut missed, mut on_floor_at_miss) = (0, 0, 0);
    let (mut closest, mut moved) = (vec![], vec![]);
    for r in 0..rows {
        let off = data.state(r)[mgt] < 0.5;
        if !(off && data.action(r)[magnet_action] > 0.5) {
            continue;
        }
        switch_ons += 1;
        let Some(end) = missed_until(data, r, magnet_action) else {
            continue;
        };
        missed += 1;
        if cube_on_floor(at(r, cube)[2], scene) {
            on_floor_at_miss += 1;
            continue;
        }
        let near = (r + 1..=end)
            .map(|k| distance(at(k, ef), at(k, cube)))
            .fold(f64::INFINITY, f64::min);
        closest.push(near);
        moved.push(distance(at(r, cube), at(end, cube)));
    }
    stats.switch_ons = Some(switch_ons);
    stats.grasp_success = Some((switch_ons - missed) as f64 / switch_ons.max(1) as f64);
    stats.grasp_misses = Some(GraspMisses {
        count: missed,
        cube_on_floor: on_floor_at_miss as f64 / missed.max(1) as f64,
        closest_quartiles: [0.25, 0.5, 0.75].map(|q| quantile(&mut closest, q)),
        cube_moved_median: quantile(&mut moved, 0.5),
    });
    Ok(())
}

/// The `q` quantile of `values` (nearest rank; 0 when empty).
fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let rank = ((values.len() as f64 * q) as usize).min(values.len() - 1);
    *values.select_nth_unstable_by(rank, f64::total_cmp).1
}

/// After the magnet was switched on at row `on`: `None` when it held the cube in some
/// state before it was switched off again or the episode ended, else the last row of
/// that on-period (the grasp missed).
fn missed_until(data: &Dataset, on: usize, magnet_action: usize) -> Option<usize> {
    let mut last = on;
    for k in on + 1..data.rows() {
        if data.episodes[k] != data.episodes[on] {
            break;
        }
        if data.holding[k] != 0 {
            return None;
        }
        last = k;
        if data.action(k)[magnet_action] < -0.5 {
            break;
        }
    }
    Some(last)
}

/// The cube (centre height `z`) has fallen off: it lies below the table top.
pub fn cube_on_floor(z: f64, scene: &Scene) -> bool {
    z < scene.table_top_z - scene.cube_size / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_dataset::ActionSource;

    /// Two exp 2 rows by hand: a switch-on that catches the cube, then the cube on the floor.
    fn two_rows() -> Dataset {
        let names = state_names(Experiment::Exp2);
        let mut data = Dataset::empty(Experiment::Exp2, ActionSource::Commanded);
        let home = SimConfig::default().home;
        let state = |o_z: f32, mgt: f32, joint0: f32| -> Vec<f32> {
            names
                .iter()
                .map(|n| match n.as_str() {
                    "o_z" => o_z,
                    "mgt" => mgt,
                    "theta0" => joint0,
                    n if n.starts_with("theta") => home[n[5..].parse::<usize>().unwrap()] as f32,
                    _ => 0.0,
                })
                .collect()
        };
        let rows = [
            (
                state(0.225, 0.0, 0.0),
                [0.2f32, 0., 0., 0., 0., 0., 0., 1.],
                state(0.225, 1.0, 0.1),
                0,
            ),
            (
                state(0.025, 1.0, 0.1),
                [0.0, 0., 0., 0., 0., 0., 0., 0.],
                state(0.025, 1.0, 0.1),
                1,
            ),
        ];
        for (s, a, next, holding) in rows {
            data.states.extend(s);
            data.actions.extend(a);
            data.next_states.extend(next);
            data.episodes.push(0);
            data.holding.push(holding);
            data.steps.push(0);
            data.stamps_ns.push(0);
        }
        data
    }

    #[test]
    fn statistics_of_hand_made_rows() {
        let stats = describe(&two_rows(), &SimConfig::default()).unwrap();
        assert_eq!(stats.transitions, 2);
        assert!((stats.commanded_spread[0] - 0.1).abs() < 1e-6);
        assert!((stats.realized_spread[0] - 0.05).abs() < 1e-6);
        assert_eq!(stats.cube_on_floor_share, Some(0.5));
        assert_eq!(stats.switch_ons, Some(1));
        assert_eq!(stats.grasp_success, Some(1.0));
        assert_eq!(stats.grasp_misses.as_ref().map(|m| m.count), Some(0));
        assert_eq!(stats.in_table_share, 0.0, "home is above the table");
        // Joint 0 turned 0.1 rad in one 1/24 s step: 2.4 rad/s against its 1.483.
        assert_eq!(stats.overspeed_share, 0.5);
        assert!(
            (stats.overspeed_max - 2.4 / 1.483).abs() < 1e-3,
            "{}",
            stats.overspeed_max
        );
    }

    #[test]
    fn a_missed_grasp_says_how_close_the_effector_came_and_where_the_cube_went() {
        let names = state_names(Experiment::Exp2);
        let home = SimConfig::default().home;
        let mut data = Dataset::empty(Experiment::Exp2, ActionSource::Commanded);
        // (ef_x, o_x, magnet on, a_mgt): switched on 0.3 m away, comes to 0.1 m while the
        // cube slides 0.02 m, switched off, never held.
        let rows = [
            (0.5f32, 0.2f32, 0.0, 1.0),
            (0.35, 0.21, 1.0, 0.0),
            (0.32, 0.22, 1.0, -1.0),
            (0.32, 0.22, 0.0, 0.0),
        ];
        let state = |(ef_x, o_x, mgt, _): (f32, f32, f32, f32)| -> Vec<f32> {
            names
                .iter()
                .map(|n| match n.as_str() {
                    "ef_x" => ef_x,
                    "o_x" => o_x,
                    "o_z" | "ef_z" => 0.225,
                    "mgt" => mgt,
                    n if n.starts_with("theta") => home[n[5..].parse::<usize>().unwrap()] as f32,
                    _ => 0.0,
                })
                .collect()
        };
        for w in rows.windows(2) {
            data.states.extend(state(w[0]));
            data.actions.extend([0., 0., 0., 0., 0., 0., 0., w[0].3]);
            data.next_states.extend(state(w[1]));
            data.episodes.push(0);
            data.holding.push(0);
            data.steps.push(0);
            data.stamps_ns.push(0);
        }
        let stats = describe(&data, &SimConfig::default()).unwrap();
        assert_eq!(stats.switch_ons, Some(1));
        assert_eq!(stats.grasp_success, Some(0.0));
        let misses = stats.grasp_misses.unwrap();
        assert_eq!(misses.count, 1);
        assert_eq!(misses.cube_on_floor, 0.0);
        assert!(
            (misses.closest_quartiles[1] - 0.1).abs() < 1e-6,
            "{misses:?}"
        );
        assert!((misses.cube_moved_median - 0.02).abs() < 1e-6, "{misses:?}");
    }

    #[test]
    fn the_state_that_ends_an_episode_is_probed_for_the_table_too() {
        let config = SimConfig::default();
        let probe = TableProbe::new(&config).unwrap();
        // Bend the shoulder down until the arm is deep in the table.
        let mut deep = config.home;
        while probe.penetration(&deep).unwrap() < 0.05 {
            deep[1] += 0.05;
            assert!(deep[1] < 2.1, "the shoulder never reached the table");
        }
        let mut data = two_rows();
        let names = state_names(Experiment::Exp2);
        let width = names.len();
        for (j, q) in deep.iter().enumerate() {
            let k = feature(&names, &format!("theta{j}")).unwrap();
            data.next_states[width + k] = *q as f32;
        }
        data.steps[1] = 7;
        let stats = describe(&data, &config).unwrap();
        let want = probe.penetration(&deep.map(|q| q as f32 as f64)).unwrap();
        assert_eq!(stats.penetration_max, want);
        assert_eq!(
            stats.penetration_max_at,
            [0, 8],
            "the last row's next state"
        );
        assert_eq!(
            stats.in_table_share,
            1.0 / 3.0,
            "three states, one in the table"
        );
    }

    #[test]
    fn the_cube_is_on_the_floor_only_below_the_table_top() {
        let scene = Scene::default();
        assert!(!cube_on_floor(0.225, &scene));
        assert!(!cube_on_floor(0.30, &scene));
        assert!(cube_on_floor(0.025, &scene));
    }
}
