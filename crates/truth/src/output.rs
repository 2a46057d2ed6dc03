//! Truth files: `truth.json` (everything), `truth.csv` (one row per edge, context and
//! horizon) and the one-step heat map; and reading a truth back with its shape checked.

use std::path::{Path, PathBuf};

use causal_arm_plots::{HeatmapScale, heatmap};

use crate::{FORMAT, Truth, TruthError};

fn file_err(path: &Path, problem: impl std::fmt::Display) -> TruthError {
    TruthError::File {
        path: path.to_owned(),
        problem: problem.to_string(),
    }
}

/// Writes `bytes` to `path` so a reader sees the old file or the whole new one, never
/// half a file, even after a crash (`atomic-write-file`: temporary sibling, fsync, rename).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), TruthError> {
    use std::io::Write;
    let mut file = atomic_write_file::AtomicWriteFile::open(path).map_err(|e| file_err(path, e))?;
    file.write_all(bytes).map_err(|e| file_err(path, e))?;
    file.commit().map_err(|e| file_err(path, e))
}

impl Truth {
    /// One row per (context, horizon, action, state).
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "context,horizon,action,state,states,active_fraction,edge,mean_effect,max_effect\n",
        );
        for m in &self.matrices {
            for (a, action) in self.action_names.iter().enumerate() {
                for (k, state) in self.state_names.iter().enumerate() {
                    let edge = m.edge(a, k, self.plan.min_fraction);
                    out.push_str(&format!(
                        "{},{},{action},{state},{},{:.6},{},{:.6e},{:.6e}\n",
                        m.context,
                        m.horizon,
                        m.states,
                        m.active_fraction[a][k],
                        serde_json::to_value(edge)
                            .ok()
                            .and_then(|v| v.as_str().map(str::to_owned))
                            .unwrap_or_default(),
                        m.mean_effect[a][k],
                        m.max_effect[a][k],
                    ));
                }
            }
        }
        out
    }
}

/// Writes `truth.json`, `truth.csv` and `truth_heatmap.{png,svg}` into `dir`.
pub fn write_all(dir: &Path, truth: &Truth) -> Result<Vec<PathBuf>, TruthError> {
    std::fs::create_dir_all(dir).map_err(|e| file_err(dir, e))?;
    let json = dir.join("truth.json");
    let text = serde_json::to_string_pretty(truth).map_err(|e| file_err(&json, e))?;
    write_atomic(&json, text.as_bytes())?;
    let csv = dir.join("truth.csv");
    write_atomic(&csv, truth.to_csv().as_bytes())?;
    let m = truth.one_step();
    let stem = dir.join("truth_heatmap");
    let values: Vec<f64> = m.active_fraction.iter().flatten().copied().collect();
    heatmap(
        &stem,
        &format!(
            "{} ground truth: share of {} states where do(a) changes s(t+1)",
            truth.experiment, m.states
        ),
        &truth.action_names,
        &truth.state_names,
        &values,
        "fraction of states",
        HeatmapScale::Linear,
    )?;
    Ok(vec![
        json,
        csv,
        stem.with_extension("png"),
        stem.with_extension("svg"),
    ])
}

/// Reads a truth from `path` (a `truth.json`, or the directory holding one), checking its
/// format and that every matrix fits its names.
pub fn load(path: &Path) -> Result<Truth, TruthError> {
    let file = if path.is_dir() {
        path.join("truth.json")
    } else {
        path.to_owned()
    };
    let text = std::fs::read_to_string(&file).map_err(|e| file_err(&file, e))?;
    let truth: Truth = serde_json::from_str(&text)
        .map_err(|e| file_err(&file, format!("not a truth file ({FORMAT}): {e}")))?;
    if truth.format != FORMAT {
        return Err(file_err(
            &file,
            format!("format {:?}, expected {FORMAT:?}", truth.format),
        ));
    }
    let (na, ns) = (truth.action_names.len(), truth.state_names.len());
    for m in &truth.matrices {
        for (what, rows) in [
            ("active_fraction", &m.active_fraction),
            ("mean_effect", &m.mean_effect),
            ("max_effect", &m.max_effect),
        ] {
            if rows.len() != na || rows.iter().any(|r| r.len() != ns) {
                return Err(file_err(
                    &file,
                    format!(
                        "matrix {what} of context {} at horizon {} is not {na} actions × {ns} states",
                        m.context, m.horizon
                    ),
                ));
            }
        }
    }
    if truth.matrix(crate::Context::ALL, 1).is_none() {
        return Err(file_err(
            &file,
            "holds no matrix of context all at horizon 1",
        ));
    }
    Ok(truth)
}
