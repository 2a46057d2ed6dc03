//! Datasets built from real generated bags: shapes, joins, episodes, cache, bad bags.

use std::path::{Path, PathBuf};

use causal_arm_bag::{BagOptions, BagReader, BagWriter, RawMessage, offered_qos_yaml};
use causal_arm_datagen::{GenerateOptions, generate};
use causal_arm_dataset::{
    ActionSource, Cache, CacheOutcome, DatasetError, Experiment, from_bag, load_bags, state_names,
};
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_protocol::RunPlan;
use causal_arm_protocol::topics;

fn tempdir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("causal-arm-dataset-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn bag(dir: &Path, experiment: Experiment, episodes: u64, steps: u64) -> PathBuf {
    let out = dir.join(format!("{experiment}"));
    let plan = RunPlan {
        episodes,
        steps_per_episode: steps,
    };
    generate(
        &GenerateOptions::new(experiment, plan, 3, &out),
        &mut |_, _| {},
    )
    .unwrap();
    out
}

/// Copies the step topics of `src` into a new bag, leaving out messages `skip` selects.
fn copy_without(src: &Path, dst: &Path, skip: impl Fn(&RawMessage, usize) -> bool) {
    copy_edited(src, dst, |raw, i| (!skip(raw, i)).then(|| raw.data.clone()));
}

/// Copies the step topics of `src` into a new bag, each message as `edit` gives its CDR
/// (`None`: left out); `edit` also gets the step's index.
fn copy_edited(src: &Path, dst: &Path, edit: impl Fn(&RawMessage, usize) -> Option<Vec<u8>>) {
    let reader = BagReader::open(src).unwrap();
    let mut writer = BagWriter::create(dst, BagOptions::default()).unwrap();
    let qos = offered_qos_yaml(true, false, true, 0);
    writer
        .add_topic::<JointState>(topics::JOINT_STATES, &qos)
        .unwrap();
    writer
        .add_topic::<PoseStamped>(topics::EF_POSE, &qos)
        .unwrap();
    writer
        .add_topic::<PoseStamped>(topics::OBJECT_POSE, &qos)
        .unwrap();
    writer
        .add_topic::<ObjectColor>(topics::OBJECT_COLOR, &qos)
        .unwrap();
    writer
        .add_topic::<MagnetState>(topics::MAGNET_STATE, &qos)
        .unwrap();
    writer.add_topic::<Action>(topics::ACTION, &qos).unwrap();
    let mut index = 0;
    for raw in reader.messages() {
        let raw = raw.unwrap();
        if raw.topic != topics::JOINT_STATES
            && raw.topic != topics::EF_POSE
            && raw.topic != topics::OBJECT_POSE
            && raw.topic != topics::OBJECT_COLOR
            && raw.topic != topics::MAGNET_STATE
            && raw.topic != topics::ACTION
        {
            continue;
        }
        if raw.topic == topics::JOINT_STATES {
            index += 1;
        }
        if let Some(data) = edit(&raw, index - 1) {
            writer
                .write_cdr(&raw.topic, raw.log_time_ns, raw.publish_time_ns, &data)
                .unwrap();
        }
    }
    writer.finish().unwrap();
}

#[test]
fn exp1_transitions_follow_the_data_model() {
    let dir = tempdir("exp1");
    let path = bag(&dir, Experiment::Exp1, 1, 300);
    let data = from_bag(&path, Some(Experiment::Exp1), ActionSource::Realized).unwrap();
    assert_eq!(data.rows(), 299);
    assert_eq!(data.state_width(), 10);
    assert_eq!(data.action_width(), 7);
    for i in 0..data.rows() - 1 {
        assert_eq!(
            data.next_state(i),
            data.state(i + 1),
            "row {i}: s(t+1) is the next row's s(t)"
        );
        for j in 0..7 {
            let realized = data.next_state(i)[j] as f64 - data.state(i)[j] as f64;
            assert!((data.action(i)[j] as f64 - realized).abs() < 1e-6);
        }
    }
    // ef is where the arm's forward kinematics puts it.
    let model = causal_arm_kinematics::ArmModel::embedded();
    for i in [0, 100, 298] {
        let s = data.state(i);
        let q: Vec<f64> = s[..7].iter().map(|&v| v as f64).collect();
        let ef = model.ef_pose(&q).unwrap().translation.vector;
        for k in 0..3 {
            assert!((ef[k] - s[7 + k] as f64).abs() < 1e-5, "row {i} ef[{k}]");
        }
    }
    let commanded = from_bag(&path, None, ActionSource::Commanded).unwrap();
    assert_eq!(commanded.experiment, Experiment::Exp1);
    assert_ne!(
        commanded.actions, data.actions,
        "commanded deltas are not what the joints did"
    );
    assert_eq!(data.sources[0].rows, 299);
    assert_eq!(data.sources[0].blake3.len(), 64);
}

#[test]
fn exp2_transitions_stay_inside_episodes() {
    let dir = tempdir("exp2");
    let path = bag(&dir, Experiment::Exp2, 3, 60);
    let data = from_bag(&path, Some(Experiment::Exp2), ActionSource::Realized).unwrap();
    assert_eq!(data.rows(), 3 * 59);
    assert_eq!(data.state_width(), 23);
    assert_eq!(data.action_width(), 8);
    let names = state_names(Experiment::Exp2);
    let colour = names.iter().position(|n| n == "o_R").unwrap();
    for i in 0..data.rows() {
        assert!(data.steps[i] < 59);
        assert_eq!(
            data.state(i)[colour],
            data.next_state(i)[colour],
            "colour is constant in an episode"
        );
        let a_mgt = data.action(i)[7];
        assert!([-1.0, 0.0, 1.0].contains(&a_mgt));
        assert!([0.0, 1.0].contains(&data.state(i)[22]));
    }
    assert_eq!(*data.episodes.last().unwrap(), 2);
    assert_ne!(
        data.state(0)[colour],
        data.state(59)[colour],
        "colour changes across episodes"
    );

    let err = from_bag(&path, Some(Experiment::Exp1), ActionSource::Realized).unwrap_err();
    assert!(matches!(err, DatasetError::WrongExperiment { .. }));
    let text = err.to_string();
    assert!(
        text.contains("holds exp2") && text.contains("expected exp1") && text.contains("exp2"),
        "{text}"
    );
}

#[test]
fn cache_returns_the_same_dataset_and_multiple_bags_concatenate() {
    let dir = tempdir("cache");
    let a = bag(&dir.join("a"), Experiment::Exp1, 1, 120);
    let b = bag(&dir.join("b"), Experiment::Exp1, 1, 80);
    let cache = Cache::new(dir.join("cache"));
    let (first, outcome) = cache
        .load_or_build(&a, Some(Experiment::Exp1), ActionSource::Realized)
        .unwrap();
    assert_eq!(outcome, CacheOutcome::Built);
    let (second, outcome) = cache
        .load_or_build(&a, Some(Experiment::Exp1), ActionSource::Realized)
        .unwrap();
    assert_eq!(outcome, CacheOutcome::Hit);
    assert_eq!(first, second, "the design too survives the cache");
    let randomized = first
        .randomized
        .as_ref()
        .expect("the bag records its design");
    assert_eq!(randomized.len(), 119);
    assert!(
        randomized.iter().all(|&m| m == 0b111_1111),
        "exp1 draws every joint"
    );
    assert_eq!(first.randomized(0, 6), Some(true));
    let (both, outcomes) = load_bags(
        &[a.clone(), b],
        Some(Experiment::Exp1),
        ActionSource::Realized,
        Some(&cache),
    )
    .unwrap();
    let how: Vec<_> = outcomes.iter().map(|(_, o)| *o).collect();
    assert_eq!(how, [CacheOutcome::Hit, CacheOutcome::Built]);
    assert_eq!(both.rows(), 119 + 79);
    assert_eq!(both.sources.len(), 2);
    assert_eq!(
        both.episodes[119], 1,
        "the second bag's episodes follow the first's"
    );
    // The cache refuses the wrong experiment too.
    let err = cache
        .load_or_build(&a, Some(Experiment::Exp2), ActionSource::Realized)
        .unwrap_err();
    assert!(err.to_string().contains("holds exp1"), "{err}");
}

#[test]
fn holes_and_gaps_are_named() {
    let dir = tempdir("holes");
    let src = bag(&dir, Experiment::Exp1, 1, 50);
    // One step without its /object/pose.
    let hole = dir.join("hole");
    copy_without(&src, &hole, |raw, step| {
        step == 20 && raw.topic == topics::OBJECT_POSE
    });
    let err = from_bag(&hole, None, ActionSource::Realized)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("hole") && err.contains("no message on /object/pose") && err.contains("stamp"),
        "{err}"
    );
    // A whole step missing.
    let gap = dir.join("gap");
    copy_without(&src, &gap, |_, step| step == 30);
    let err = from_bag(&gap, None, ActionSource::Realized)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("gap on /joint_states") && err.contains("expected a step of"),
        "{err}"
    );
    // A topic missing entirely.
    let none = dir.join("none");
    copy_without(&src, &none, |raw, _| raw.topic == topics::MAGNET_STATE);
    let err = from_bag(&none, None, ActionSource::Realized)
        .unwrap_err()
        .to_string();
    assert!(err.contains("/magnet/state"), "{err}");
    // Not a bag.
    let err = from_bag(&dir.join("missing"), None, ActionSource::Realized)
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing"), "{err}");
}

#[test]
fn the_default_action_follows_the_arm_the_bag_was_recorded_with() {
    let dir = tempdir("arm-action");
    let kinematic = bag(&dir, Experiment::Exp1, 1, 20);
    let dynamic = dir.join("dynamic");
    let mut options = GenerateOptions::new(
        Experiment::Exp1,
        RunPlan {
            episodes: 1,
            steps_per_episode: 20,
        },
        3,
        &dynamic,
    );
    options.sim.arm = causal_arm_sim::ArmMode::Dynamic;
    generate(&options, &mut |_, _| {}).unwrap();
    assert_eq!(
        ActionSource::of_bags(std::slice::from_ref(&kinematic)).unwrap(),
        ActionSource::Realized
    );
    assert_eq!(
        ActionSource::of_bags(std::slice::from_ref(&dynamic)).unwrap(),
        ActionSource::Commanded
    );
    let mixed = ActionSource::of_bags(&[kinematic.clone(), dynamic.clone()])
        .unwrap_err()
        .to_string();
    assert!(
        mixed.contains("different arms") && mixed.contains("--action"),
        "{mixed}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bag recorded before `Action.design` existed (the fuzz corpus holds two) still reads,
/// as a bag whose design is not recorded; with a bag that records one, the design of the
/// whole is unknown.
#[test]
fn a_bag_without_a_recorded_design_reads_and_says_so() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/corpus/bag/exp1s.mcap");
    let old = from_bag(&corpus, Some(Experiment::Exp1), ActionSource::Realized).unwrap();
    assert!(old.rows() > 0);
    assert_eq!(old.randomized, None);
    assert_eq!(old.randomized(0, 0), None);
    assert!(
        old.design_summary().contains("not recorded"),
        "{}",
        old.design_summary()
    );
    let dir = tempdir("design");
    let new = bag(&dir, Experiment::Exp1, 1, 50);
    let (both, _) = load_bags(
        &[new, corpus],
        Some(Experiment::Exp1),
        ActionSource::Realized,
        None,
    )
    .unwrap();
    assert_eq!(
        both.randomized, None,
        "known only where every bag records it"
    );
}

/// A design the bag's reader cannot take (an unknown family) is an error naming the bag,
/// the topic, the step's stamp and the component.
#[test]
fn a_malformed_design_is_an_error_naming_the_step_and_component() {
    let dir = tempdir("bad-design");
    let good = bag(&dir, Experiment::Exp1, 1, 30);
    let bad = dir.join("bad");
    copy_edited(&good, &bad, |raw, i| {
        if raw.topic != topics::ACTION || i != 10 {
            return Some(raw.data.clone());
        }
        let mut action: Action = causal_arm_msgs::from_cdr(&raw.data).unwrap();
        action.design[2].family = 7;
        Some(causal_arm_msgs::to_cdr(&action).unwrap())
    });
    let err = from_bag(&bad, Some(Experiment::Exp1), ActionSource::Realized).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("/babbler/action at"), "{text}");
    assert!(text.contains("design[2]: family 7"), "{text}");
}
