//! Fuzz targets for every reader of outside input: CDR of each message type, the bag
//! reader, the dataset builder, the URDF loader and the trainer's service handlers.
//!
//! A target must never panic, hang or allocate without bound on any input; where it
//! accepts an input, it checks a property (a decoded message re-encodes; a loaded arm has
//! finite poses; a successful reply holds only finite numbers). The same targets run
//! under cargo-fuzz (`fuzz_targets/`, `tests/fuzz/run.sh`) and, over the seed corpus in
//! `tests/corpus/<target>/` plus bounded random mutations of it, in the test command
//! ([`exercise`]).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use causal_arm_dataset::ActionSource;
use causal_arm_models::serve::ModelSet;
use causal_arm_msgs::srv::{
    GetModelInfo_Request, PredictAction_Request, PredictNextState_Request, Rollout_Request,
};
use causal_arm_msgs::{
    MessageTypeVisitor, RosMessage, cdr_to_json, from_cdr, to_cdr, visit_message_type,
};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

mod mutate;

/// One fuzz target: what part of the product the bytes are fed to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// `<ros type>\n<CDR bytes>`: decoding any message or service type.
    Cdr,
    /// An `.mcap` file alone in a bag directory: the checked reader, strict and salvaging.
    Bag,
    /// An `.mcap` file alone in a bag directory: the dataset builder.
    Dataset,
    /// URDF text: the kinematics loader, then forward kinematics at the zero pose.
    Urdf,
    /// `<service>\n<CDR request>`: the trainer's service handlers over a small exp1 model.
    TrainerRequest,
}

impl Target {
    /// Every target, in the order the test command runs them.
    pub const ALL: [Target; 5] = [
        Target::Cdr,
        Target::Bag,
        Target::Dataset,
        Target::Urdf,
        Target::TrainerRequest,
    ];

    /// The name of its cargo-fuzz binary and of its corpus folder.
    pub fn name(self) -> &'static str {
        match self {
            Target::Cdr => "cdr",
            Target::Bag => "bag",
            Target::Dataset => "dataset",
            Target::Urdf => "urdf",
            Target::TrainerRequest => "trainer_request",
        }
    }

    /// The target called `name`, if any.
    pub fn from_name(name: &str) -> Option<Target> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Feeds `data` to the target; panics only on a bug (a broken property or a panic of
    /// the code under test).
    pub fn run(self, data: &[u8]) {
        match self {
            Target::Cdr => cdr(data),
            Target::Bag => bag(data),
            Target::Dataset => dataset(data),
            Target::Urdf => urdf(data),
            Target::TrainerRequest => trainer_request(data),
        }
    }
}

/// The repository's `tests/corpus/`.
pub fn corpus_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/corpus")
}

/// Splits `<header>\n<payload>`; `None` if there is no newline or the header is not UTF-8.
fn split_header(data: &[u8]) -> Option<(&str, &[u8])> {
    let newline = data.iter().position(|&b| b == b'\n')?;
    let header = std::str::from_utf8(&data[..newline]).ok()?;
    Some((header, &data[newline + 1..]))
}

/// Decodes as the typed message; whatever decodes must encode again, and that encoding
/// must decode and encode to the same bytes. The JSON view (`topic echo`) must not panic;
/// JSON has no NaN, so it is not held to the round trip.
fn cdr(data: &[u8]) {
    let Some((ros_type, bytes)) = split_header(data) else {
        return;
    };
    let _ = cdr_to_json(ros_type, bytes);
    let _ = visit_message_type(ros_type, TypedRoundTrip(bytes));
}

/// The typed round trip of [`cdr`].
struct TypedRoundTrip<'a>(&'a [u8]);

impl MessageTypeVisitor for TypedRoundTrip<'_> {
    type Output = ();
    fn visit<M: RosMessage>(self) {
        let Ok(message) = from_cdr::<M>(self.0) else {
            return;
        };
        let again = to_cdr(&message)
            .unwrap_or_else(|e| panic!("{}: decoded but does not encode again: {e}", M::ROS_TYPE));
        let back = from_cdr::<M>(&again)
            .unwrap_or_else(|e| panic!("{}: its own encoding does not decode: {e}", M::ROS_TYPE));
        let twice = to_cdr(&back).expect("encodes");
        assert_eq!(again, twice, "{}: decode/encode is not stable", M::ROS_TYPE);
    }
}

/// A scratch bag directory holding `data` as its only `.mcap` file, removed when dropped
/// (the corpus test runs every input on a thread of its own).
fn scratch_bag(data: &[u8]) -> tempfile::TempDir {
    let dir = tempfile::Builder::new()
        .prefix("causal_arm_fuzz_")
        .tempdir()
        .expect("scratch directory");
    std::fs::write(dir.path().join("fuzz_0.mcap"), data).expect("scratch bag");
    dir
}

fn bag(data: &[u8]) {
    use causal_arm_bag::{BagReader, ReadPolicy};
    let dir = scratch_bag(data);
    for policy in [ReadPolicy::Strict, ReadPolicy::Salvage] {
        if let Ok(reader) = BagReader::open_with(dir.path(), policy) {
            for message in reader.messages() {
                if message.is_err() {
                    break;
                }
            }
        }
    }
}

fn dataset(data: &[u8]) {
    let dir = scratch_bag(data);
    if let Ok(set) = causal_arm_dataset::from_bag(dir.path(), None, ActionSource::Realized) {
        assert!(set.rows() > 0, "a dataset without transitions was accepted");
    }
}

fn urdf(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(arm) = causal_arm_kinematics::ArmModel::from_urdf_str(text, "<fuzz>") else {
        return;
    };
    let zero = vec![0.0; arm.joint_names().len()];
    if let Ok(pose) = arm.ef_pose(&zero) {
        let v = causal_arm_kinematics::pose_vector(&pose);
        assert!(v.iter().all(|x| x.is_finite()), "non-finite pose {v:?}");
    }
}

/// The small exp1 model of `tests/corpus/trainer_model/` (FM and both IMs, 8 units wide).
fn model_set() -> &'static ModelSet {
    static MODELS: OnceLock<ModelSet> = OnceLock::new();
    MODELS.get_or_init(|| {
        ModelSet::load(&corpus_root().join("trainer_model"), "fm", "im-mono", false)
            .expect("tests/corpus/trainer_model loads")
    })
}

/// Checks the reply contract: success with finite numbers, or a refusal saying why.
fn check_reply(service: &str, success: bool, message: &str, numbers: &[f64]) {
    if success {
        assert!(
            numbers.iter().all(|v| v.is_finite()),
            "{service}: success with non-finite numbers"
        );
    } else {
        assert!(!message.is_empty(), "{service}: refused without a reason");
    }
}

fn decode<M: RosMessage>(bytes: &[u8]) -> Option<M> {
    from_cdr::<M>(bytes).ok()
}

fn trainer_request(data: &[u8]) {
    let Some((service, bytes)) = split_header(data) else {
        return;
    };
    let models = model_set();
    match service {
        "predict_next_state" => {
            if let Some(req) = decode::<PredictNextState_Request>(bytes) {
                let r = models.predict_next_state(&req);
                check_reply(service, r.success, &r.message, &r.next_state);
            }
        }
        "predict_action" => {
            if let Some(req) = decode::<PredictAction_Request>(bytes) {
                let r = models.predict_action(&req);
                check_reply(service, r.success, &r.message, &r.action);
            }
        }
        "rollout" => {
            if let Some(req) = decode::<Rollout_Request>(bytes) {
                let r = models.rollout(&req);
                check_reply(service, r.success, &r.message, &r.states);
            }
        }
        "model_info" => {
            if let Some(req) = decode::<GetModelInfo_Request>(bytes) {
                let r = models.model_info(&req);
                check_reply(service, r.success, &r.message, &[]);
            }
        }
        _ => {}
    }
}

/// What one bounded run of a target did.
#[derive(Debug, Default)]
pub struct Exercise {
    /// Corpus entries replayed as they are.
    pub seeds: usize,
    /// Mutated inputs tried after them.
    pub mutants: usize,
    /// Inputs that panicked or took over the hang limit, saved under `findings/`.
    pub findings: Vec<(PathBuf, String)>,
}

/// An input taking longer than this counts as a hang.
pub const HANG_LIMIT: Duration = Duration::from_secs(10);

/// Replays every seed of `target` in `corpus/<name>/`, then feeds random mutations of them
/// (seeded by `seed`) until `budget` has passed. Panicking or hanging inputs are written to
/// `findings/<name>/<blake3>` and returned: a finding, once fixed, becomes a corpus entry.
pub fn exercise(
    target: Target,
    corpus: &Path,
    findings: &Path,
    budget: Duration,
    seed: u64,
) -> std::io::Result<Exercise> {
    let seeds = read_corpus(&corpus.join(target.name()))?;
    let mut report = Exercise {
        seeds: seeds.len(),
        ..Exercise::default()
    };
    for input in &seeds {
        try_input(target, input, findings, &mut report)?;
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let start = Instant::now();
    while !seeds.is_empty() && start.elapsed() < budget && report.findings.len() < 10 {
        let base = &seeds[rng.random_range(0..seeds.len())];
        let other = &seeds[rng.random_range(0..seeds.len())];
        let input = mutate::mutate(base, other, &mut rng);
        report.mutants += 1;
        try_input(target, &input, findings, &mut report)?;
    }
    Ok(report)
}

/// The files of a corpus folder, in name order.
fn read_corpus(dir: &Path) -> std::io::Result<Vec<Vec<u8>>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    paths.retain(|p| p.is_file());
    paths.sort();
    paths.iter().map(std::fs::read).collect()
}

/// Runs one input on a worker thread, so a hang is noticed instead of waited out.
fn try_input(
    target: Target,
    input: &[u8],
    findings: &Path,
    report: &mut Exercise,
) -> std::io::Result<()> {
    let owned = input.to_vec();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let outcome = std::panic::catch_unwind(|| target.run(&owned));
        let _ = tx.send(outcome.map_err(|e| panic_text(&*e)));
    });
    let problem = match rx.recv_timeout(HANG_LIMIT) {
        Ok(Ok(())) => return Ok(()),
        Ok(Err(panic)) => format!("panicked: {panic}"),
        Err(_) => format!("took over {HANG_LIMIT:?} (hang)"),
    };
    let dir = findings.join(target.name());
    std::fs::create_dir_all(&dir)?;
    let path = dir.join(blake3::hash(input).to_hex().as_str());
    std::fs::write(&path, input)?;
    report.findings.push((path, problem));
    Ok(())
}

fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "(no message)".into())
}
