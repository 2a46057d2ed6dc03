//! Files of an explanation: `shap_values.safetensors` (attributions, observations and
//! background, readable with numpy), `explanation.json` (settings, timing, mean |SHAP|),
//! `relevance.json` / `relevance.csv`, the heat map and the partial dependence plots.
//! Every file is written to a temporary name and renamed, so a crash never leaves half a file.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use causal_arm_models::mental::MentalSimulation;
use causal_arm_plots::{
    Curve, HeatmapScale, Scatter, curves_with_error_bars, heatmap, scatter, scatter_grid,
};
use safetensors::{Dtype, tensor::TensorView};
use serde_json::json;

use crate::{ExplainError, Explanation, Relevance, Result};

pub(crate) fn file_err(path: &Path, problem: impl std::fmt::Display) -> ExplainError {
    ExplainError::File {
        path: path.display().to_string(),
        problem: problem.to_string(),
    }
}

/// Writes `bytes` to `path` so a reader sees the old file or the whole new one, never
/// half a file, even after a crash (`atomic-write-file`: temporary sibling, fsync, rename).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let mut file = atomic_write_file::AtomicWriteFile::open(path).map_err(|e| file_err(path, e))?;
    file.write_all(bytes).map_err(|e| file_err(path, e))?;
    file.commit().map_err(|e| file_err(path, e))
}

/// Writes `value` as pretty JSON (and a newline) to `path`, atomically.
pub(crate) fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| file_err(path, e))? + "\n";
    write_atomic(path, text.as_bytes())
}

fn le_bytes_f64(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn le_bytes_f32(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// `shap_values.safetensors`: `values` F64 `[n_obs, n_inputs, n_outputs]`, `expected` F64
/// `[n_outputs]`, `outputs` F64 `[n_obs, n_outputs]`, `observations` F32
/// `[n_obs, n_inputs]`, `background` F32 `[n_bg, n_inputs]`, `background_weights` F64
/// `[n_bg]`; metadata `input_names`, `output_names` (JSON lists) and `method`.
pub fn write_shap_values(path: &Path, e: &Explanation) -> Result<()> {
    let a = &e.attributions;
    let n_bg = e.background.rows();
    let tensors: Vec<(&str, Dtype, Vec<usize>, Vec<u8>)> = vec![
        (
            "values",
            Dtype::F64,
            vec![a.n_obs, a.n_inputs, a.n_outputs],
            le_bytes_f64(&a.values),
        ),
        (
            "expected",
            Dtype::F64,
            vec![a.n_outputs],
            le_bytes_f64(&a.expected),
        ),
        (
            "outputs",
            Dtype::F64,
            vec![a.n_obs, a.n_outputs],
            le_bytes_f64(&a.outputs),
        ),
        (
            "observations",
            Dtype::F32,
            vec![a.n_obs, a.n_inputs],
            le_bytes_f32(&e.observations),
        ),
        (
            "background",
            Dtype::F32,
            vec![n_bg, a.n_inputs],
            le_bytes_f32(e.background.data()),
        ),
        (
            "background_weights",
            Dtype::F64,
            vec![n_bg],
            le_bytes_f64(e.background.weights()),
        ),
    ];
    let views = tensors
        .iter()
        .map(|(name, dtype, shape, bytes)| {
            TensorView::new(*dtype, shape.clone(), bytes)
                .map(|v| (name.to_string(), v))
                .map_err(|err| file_err(path, err))
        })
        .collect::<Result<Vec<_>>>()?;
    let metadata: HashMap<String, String> = [
        ("input_names", serde_json::to_string(&e.input_names)),
        ("output_names", serde_json::to_string(&e.output_names)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_owned(), v.expect("a list of strings serialises")))
    .chain([("method".to_owned(), e.settings.method.to_string())])
    .collect();
    let bytes = safetensors::serialize(views, Some(metadata)).map_err(|err| file_err(path, err))?;
    write_atomic(path, &bytes)
}

/// The summary `explanation.json`: settings, sizes, timing, efficiency and mean |SHAP|.
pub fn summary_json(e: &Explanation) -> serde_json::Value {
    json!({
        "method": e.settings.method,
        "experiment": e.experiment.to_string(),
        "settings": e.settings,
        "observations": e.attributions.n_obs,
        "background": e.background.rows(),
        "seconds": e.seconds,
        "efficiency_error": e.efficiency_error(),
        "observation_rows": e.observation_rows,
        "input_names": e.input_names,
        "output_names": e.output_names,
        "expected": e.attributions.expected,
        "mean_abs": e
            .attributions
            .mean_abs()
            .chunks(e.attributions.n_outputs)
            .map(|r| r.to_vec())
            .collect::<Vec<_>>(),
    })
}

/// Pairs shown in the paper's PDP figure (exp2), drawn first in the grid when present.
const PAPER_PAIRS: [(&str, &str); 4] = [
    ("a0", "theta0"),
    ("a0", "o_x"),
    ("a2", "o_B"),
    ("a_mgt", "o_z"),
];

/// Panels of the PDP grid.
pub const GRID_PANELS: usize = 12;

/// What [`write_all`] wrote.
#[derive(Debug, Clone)]
pub struct Written {
    /// Every file, in the order written.
    pub files: Vec<PathBuf>,
}

/// Writes every output of an explanation into `dir` (created if missing) and returns the
/// paths. Per-pair PDPs go to `dir/pdp/<action>__<state>.{png,svg}`.
pub fn write_all(
    dir: &Path,
    e: &Explanation,
    relevance: &Relevance,
    per_pair_plots: bool,
) -> Result<Written> {
    std::fs::create_dir_all(dir).map_err(|err| file_err(dir, err))?;
    let mut out = OutputDir {
        dir,
        e,
        relevance,
        files: Vec::new(),
    };
    out.write_data()?;
    out.write_heatmap()?;
    out.write_pdp_grid()?;
    if per_pair_plots {
        out.write_pair_plots()?;
    }
    Ok(Written { files: out.files })
}

/// One explanation being written into one directory: what every file is made from, and
/// the files written so far (in order), so each kind of output is one method.
struct OutputDir<'a> {
    dir: &'a Path,
    e: &'a Explanation,
    relevance: &'a Relevance,
    files: Vec<PathBuf>,
}

impl OutputDir<'_> {
    /// The numbers: attributions (safetensors), the summary and the relevance report
    /// (JSON and CSV), for scripts rather than readers.
    fn write_data(&mut self) -> Result<()> {
        let (dir, e, relevance) = (self.dir, self.e, self.relevance);
        let values = dir.join("shap_values.safetensors");
        write_shap_values(&values, e)?;
        self.files.push(values);
        let summary = dir.join("explanation.json");
        write_atomic(
            &summary,
            (serde_json::to_string_pretty(&summary_json(e)).expect("JSON values serialise") + "\n")
                .as_bytes(),
        )?;
        self.files.push(summary);
        let rel_json = dir.join("relevance.json");
        write_atomic(
            &rel_json,
            (serde_json::to_string_pretty(relevance).expect("the report serialises") + "\n")
                .as_bytes(),
        )?;
        self.files.push(rel_json);
        let rel_csv = dir.join("relevance.csv");
        write_atomic(&rel_csv, relevance.to_csv().as_bytes())?;
        self.files.push(rel_csv);
        Ok(())
    }

    /// The method's name as the figure titles spell it.
    fn method(&self) -> &'static str {
        match self.e.settings.method {
            crate::Method::Deep => "Deep SHAP",
            crate::Method::Kernel => "Kernel SHAP",
        }
    }

    /// The paper's knowledge-extraction figure: mean |SHAP| of every action on every
    /// state feature, on a log scale because the values span decades.
    fn write_heatmap(&mut self) -> Result<()> {
        let (e, relevance) = (self.e, self.relevance);
        let stem = self.dir.join("heatmap");
        let flat: Vec<f64> = relevance.mean_abs_shap.iter().flatten().copied().collect();
        heatmap(
            &stem,
            &format!(
                "{} forward model: mean |{}| of actions on s(t+1), {} observations",
                e.experiment,
                self.method(),
                e.attributions.n_obs
            ),
            &relevance.action_names,
            &relevance.state_names,
            &flat,
            "mean |SHAP| (units of the state feature)",
            HeatmapScale::Log,
        )?;
        self.files
            .extend([stem.with_extension("png"), stem.with_extension("svg")]);
        Ok(())
    }

    /// The PDP grid of [`GRID_PANELS`] pairs: the paper's pairs first, so the figure can
    /// be set beside the paper's, then the strongest others.
    fn write_pdp_grid(&mut self) -> Result<()> {
        let panels: Vec<Scatter> = grid_pairs(self.relevance)
            .iter()
            .map(|&(a, j)| self.panel(a, j))
            .collect();
        let grid = self.dir.join("pdp_grid");
        scatter_grid(
            &grid,
            &format!(
                "{} partial dependence ({}): action value vs its contribution",
                self.e.experiment,
                self.method()
            ),
            &panels,
            4,
        )?;
        self.files
            .extend([grid.with_extension("png"), grid.with_extension("svg")]);
        Ok(())
    }

    /// One PDP per (action, state feature) pair, for looking up any pair the grid leaves
    /// out.
    fn write_pair_plots(&mut self) -> Result<()> {
        let relevance = self.relevance;
        let pdp = self.dir.join("pdp");
        std::fs::create_dir_all(&pdp).map_err(|err| file_err(&pdp, err))?;
        for a in 0..relevance.action_names.len() {
            for j in 0..relevance.state_names.len() {
                let stem = pdp.join(format!(
                    "{}__{}",
                    relevance.action_names[a], relevance.state_names[j]
                ));
                scatter(&stem, &self.panel(a, j))?;
                self.files
                    .extend([stem.with_extension("png"), stem.with_extension("svg")]);
            }
        }
        Ok(())
    }

    /// The partial dependence panel of action `a` on state feature `j`, the same in the
    /// grid and in the per-pair files.
    fn panel(&self, a: usize, j: usize) -> Scatter {
        let relevance = self.relevance;
        Scatter {
            title: format!(
                "{} → {}",
                relevance.action_names[a], relevance.state_names[j]
            ),
            x_label: relevance.action_names[a].clone(),
            y_label: format!("SHAP on {}(t+1)", relevance.state_names[j]),
            points: self.e.dependence(a, j),
        }
    }
}

/// The (action, state) pairs of the PDP grid: [`PAPER_PAIRS`] present in this model,
/// then the highest-scoring other pairs up to [`GRID_PANELS`].
fn grid_pairs(relevance: &Relevance) -> Vec<(usize, usize)> {
    let index = |names: &[String], n: &str| names.iter().position(|x| x == n);
    let mut pairs: Vec<(usize, usize)> = PAPER_PAIRS
        .iter()
        .filter_map(|(a, s)| {
            Some((
                index(&relevance.action_names, a)?,
                index(&relevance.state_names, s)?,
            ))
        })
        .collect();
    let mut ranked: Vec<(usize, usize, f64)> = (0..relevance.action_names.len())
        .flat_map(|a| (0..relevance.state_names.len()).map(move |j| (a, j, relevance.score(a, j))))
        .collect();
    ranked.sort_by(|p, q| q.2.total_cmp(&p.2));
    for (a, j, _) in ranked {
        if pairs.len() >= GRID_PANELS {
            break;
        }
        if !pairs.contains(&(a, j)) {
            pairs.push((a, j));
        }
    }
    pairs
}

/// The mental-simulation figure (θ and ef MAE per step, mean ± std, log scale) at
/// `stem.{png,svg}`; also redrawn by `causal-arm explain` beside the SHAP figures.
pub fn draw_mental_simulation(
    stem: &std::path::Path,
    result: &MentalSimulation,
    experiment: &str,
) -> Result<()> {
    let plotted: Vec<Curve> = result
        .curves
        .iter()
        .filter(|c| c.group == "theta" || c.group == "ef" || c.group == "ef_pos")
        .map(|c| Curve {
            label: format!("{} [{}]", c.group, c.unit),
            points: c
                .mean
                .iter()
                .zip(&c.std)
                .enumerate()
                .map(|(k, (&m, &s))| ((k + 1) as f64, m, s))
                .collect(),
        })
        .collect();
    curves_with_error_bars(
        stem,
        &format!(
            "{experiment} mental simulation: FM chained over {} trajectories",
            result.trajectories
        ),
        "step",
        "MAE (mean ± std)",
        &plotted,
    )?;
    Ok(())
}
