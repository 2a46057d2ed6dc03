//! Writes the generated part of the seed corpus under `tests/corpus/`: every message and
//! service type's default value and one recorded message per topic of the given bags
//! (`cdr/`), the bags' `.mcap` files (`bag/`, `dataset/`), the project's URDFs (`urdf/`)
//! and valid requests of each trainer service (`trainer_request/`).
//!
//! Usage: `cargo run -p causal_arm_fuzz --bin seed_corpus -- BAG...` (small bags; the model
//! of `tests/corpus/trainer_model/` is written by `causal-arm train`, see tests/fuzz/README.md).

use std::path::{Path, PathBuf};

use anyhow::Context;
use causal_arm_bag::BagReader;
use causal_arm_dataset::{Experiment, action_names, state_names};
use causal_arm_fuzz::corpus_root;
use causal_arm_msgs::srv::{
    GetModelInfo_Request, PredictAction_Request, PredictNextState_Request, Rollout_Request,
};
use causal_arm_msgs::{MessageTypeVisitor, RosMessage, message_types, to_cdr, visit_message_type};

struct DefaultCdr;

impl MessageTypeVisitor for DefaultCdr {
    type Output = Vec<u8>;
    fn visit<M: RosMessage>(self) -> Vec<u8> {
        to_cdr(&M::default()).expect("a default value encodes")
    }
}

fn with_header(header: &str, payload: &[u8]) -> Vec<u8> {
    let mut out = format!("{header}\n").into_bytes();
    out.extend_from_slice(payload);
    out
}

fn file_name(ros_type: &str) -> String {
    ros_type.replace('/', "_")
}

fn write(dir: &Path, name: &str, data: &[u8]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join(name), data).with_context(|| format!("writing {name}"))
}

fn main() -> anyhow::Result<()> {
    let root = corpus_root();
    let bags: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    for ros_type in message_types() {
        let cdr = visit_message_type(ros_type, DefaultCdr)?;
        write(
            &root.join("cdr"),
            &format!("{}_default", file_name(ros_type)),
            &with_header(ros_type, &cdr),
        )?;
    }
    for bag in &bags {
        let reader = BagReader::open(bag)?;
        let types: std::collections::BTreeMap<String, String> = reader
            .topics()
            .into_iter()
            .map(|t| (t.name, t.ros_type))
            .collect();
        let mut seen = std::collections::BTreeSet::new();
        for message in reader.messages() {
            let message = message?;
            if seen.insert(message.topic.clone()) {
                let ros_type = &types[&message.topic];
                let name = format!(
                    "{}_{}",
                    file_name(ros_type),
                    bag.file_name().unwrap().to_string_lossy()
                );
                write(
                    &root.join("cdr"),
                    &name,
                    &with_header(ros_type, &message.data),
                )?;
            }
        }
        let mcap = std::fs::read_dir(bag)?
            .map(|e| e.map(|e| e.path()))
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .find(|p| p.extension().is_some_and(|x| x == "mcap"))
            .context("no .mcap in the bag")?;
        let data = std::fs::read(&mcap)?;
        let name = format!("{}.mcap", bag.file_name().unwrap().to_string_lossy());
        write(&root.join("bag"), &name, &data)?;
        write(&root.join("dataset"), &name, &data)?;
    }
    let urdf_dir = root.join("../../urdf");
    for entry in std::fs::read_dir(&urdf_dir)? {
        let path = entry?.path();
        if path.extension().is_some_and(|x| x == "urdf") {
            write(
                &root.join("urdf"),
                &path.file_name().unwrap().to_string_lossy(),
                &std::fs::read(&path)?,
            )?;
        }
    }
    write_trainer_requests(&root.join("trainer_request"))
}

/// One valid request of each service for the exp1 model, and refused ones.
fn write_trainer_requests(dir: &Path) -> anyhow::Result<()> {
    let (sw, aw) = (
        state_names(Experiment::Exp1).len(),
        action_names(Experiment::Exp1).len(),
    );
    let ramp = |n: usize| (0..n).map(|i| 0.01 * i as f64).collect::<Vec<_>>();
    // (file name, service, CDR of the request)
    let requests = [
        (
            "predict_next_state",
            "predict_next_state",
            to_cdr(&PredictNextState_Request {
                state: ramp(2 * sw),
                action: ramp(2 * aw),
                rows: 2,
            })?,
        ),
        (
            "predict_next_state_wrong_rows",
            "predict_next_state",
            to_cdr(&PredictNextState_Request {
                state: ramp(sw),
                action: ramp(aw),
                rows: 3,
            })?,
        ),
        (
            "predict_action",
            "predict_action",
            to_cdr(&PredictAction_Request {
                state: ramp(sw),
                next_state: ramp(sw),
                rows: 1,
            })?,
        ),
        (
            "rollout",
            "rollout",
            to_cdr(&Rollout_Request {
                initial_state: ramp(sw),
                actions: ramp(3 * aw),
                steps: 3,
            })?,
        ),
        (
            "model_info",
            "model_info",
            to_cdr(&GetModelInfo_Request { model: "fm".into() })?,
        ),
        (
            "model_info_unknown",
            "model_info",
            to_cdr(&GetModelInfo_Request {
                model: "nope".into(),
            })?,
        ),
    ];
    for (name, service, cdr) in requests {
        write(dir, name, &with_header(service, &cdr))?;
    }
    Ok(())
}
