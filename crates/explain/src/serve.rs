//! What `/explainer/explain` answers, without DDS: attributions for the caller's rows
//! against a background from the node's data; malformed requests get a `success = false`
//! reply saying what is wrong.

use causal_arm_scoring::Decision;
use std::collections::HashMap;
use std::sync::Mutex;

use causal_arm_models::serve::check_batch;
use causal_arm_msgs::msg::Relevance as RelevanceMsg;
use causal_arm_msgs::srv::{Explain_Request, Explain_Response};
use causal_arm_msgs::std_msgs::msg::Header;
use causal_arm_shap::{Background, kmeans};

use causal_arm_dataset::Dataset;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;

use crate::{Explainer, Method, Relevance, Settings, forward_inputs};

/// Most rows one Deep SHAP request may carry (≈ 5 ms per row against 100 references on the
/// exp2 FM, so a full request stays within a few seconds).
pub const MAX_DEEP_ROWS: usize = 1000;
/// Most rows one Kernel SHAP request may carry (≈ 0.12 s per row).
pub const MAX_KERNEL_ROWS: usize = 50;
/// Most background rows a request may ask for.
pub const MAX_BACKGROUND: usize = 1000;
/// Rows of the data kept as the background pool (a uniform sample).
pub const POOL_ROWS: usize = 20_000;

/// The explainer node's state: model, background pool and default settings.
pub struct ExplainService {
    explainer: Explainer,
    /// Rows `[n, inputs]` the background is drawn from (pre-shuffled, so the first `k` are
    /// a uniform sample).
    pool: Vec<f32>,
    deep: Settings,
    kernel: Settings,
    /// k-means summaries by size, computed once.
    kmeans: Mutex<HashMap<usize, Background>>,
}

fn error(message: String) -> Explain_Response {
    Explain_Response {
        success: false,
        message,
        ..Default::default()
    }
}

impl ExplainService {
    /// Serves `explainer` with backgrounds drawn from `pool` (`[n, inputs]`, already in
    /// random order) and the defaults of `deep` and `kernel`.
    pub fn new(explainer: Explainer, pool: Vec<f32>, deep: Settings, kernel: Settings) -> Self {
        Self {
            explainer,
            pool,
            deep,
            kernel,
            kmeans: Mutex::new(HashMap::new()),
        }
    }

    /// Serves `explainer` with backgrounds drawn from a seeded uniform sample of `data`'s
    /// transitions (at most [`POOL_ROWS`]), and each method's default settings with `seed`.
    pub fn on_data(explainer: Explainer, data: &Dataset, seed: u64) -> Self {
        let mut rows: Vec<usize> = (0..data.rows()).collect();
        rows.shuffle(&mut StdRng::seed_from_u64(seed));
        rows.truncate(POOL_ROWS);
        let pool = forward_inputs(data, &rows);
        let (mut deep, mut kernel) = (
            Settings::for_method(Method::Deep),
            Settings::for_method(Method::Kernel),
        );
        deep.seed = seed;
        kernel.seed = seed;
        Self::new(explainer, pool, deep, kernel)
    }

    /// The explainer behind the service.
    pub fn explainer(&self) -> &Explainer {
        &self.explainer
    }

    fn pool_rows(&self) -> usize {
        self.pool.len() / self.explainer.n_inputs()
    }

    fn background(&self, method: Method, rows: usize) -> Result<Background, String> {
        let width = self.explainer.n_inputs();
        match method {
            Method::Deep => {
                Background::sample(&self.pool[..rows * width], width).map_err(|e| e.to_string())
            }
            Method::Kernel => {
                let mut cache = self.kmeans.lock().unwrap_or_else(|p| p.into_inner());
                if let Some(b) = cache.get(&rows) {
                    return Ok(b.clone());
                }
                let b =
                    kmeans(&self.pool, width, rows, self.kernel.seed).map_err(|e| e.to_string())?;
                cache.insert(rows, b.clone());
                Ok(b)
            }
        }
    }

    /// Answers one request; never panics on its content.
    pub fn explain(&self, req: &Explain_Request) -> Explain_Response {
        match self.try_explain(req) {
            Ok(reply) => reply,
            Err(message) => error(message),
        }
    }

    fn try_explain(&self, req: &Explain_Request) -> Result<Explain_Response, String> {
        let method: Method = if req.method.is_empty() {
            Method::Deep
        } else {
            req.method.parse()?
        };
        let settings = match method {
            Method::Deep => &self.deep,
            Method::Kernel => &self.kernel,
        };
        let limit = match method {
            Method::Deep => MAX_DEEP_ROWS,
            Method::Kernel => MAX_KERNEL_ROWS,
        };
        let rows = req.rows as usize;
        if rows == 0 {
            return Err("rows must be at least 1".into());
        }
        if rows > limit {
            return Err(format!(
                "rows = {rows} exceeds the {method} SHAP limit of {limit} per request; split the batch"
            ));
        }
        let background = match req.background as usize {
            0 => settings.background,
            b => b,
        };
        let available = self.pool_rows().min(MAX_BACKGROUND);
        if background > available {
            return Err(format!(
                "background = {background} exceeds the {available} rows available"
            ));
        }
        let (sw, aw) = (
            self.explainer.state_names().len(),
            self.explainer.action_names().len(),
        );
        check_batch("state", &req.state, rows, sw)?;
        check_batch("action", &req.action, rows, aw)?;
        let mut x = Vec::with_capacity(rows * (sw + aw));
        for r in 0..rows {
            x.extend(req.state[r * sw..(r + 1) * sw].iter().map(|&v| v as f32));
            x.extend(req.action[r * aw..(r + 1) * aw].iter().map(|&v| v as f32));
        }
        let bg = self.background(method, background)?;
        let (a, _) = self
            .explainer
            .attribute(&x, &bg, settings)
            .map_err(|e| e.to_string())?;
        // Reply layout: rows × n_outputs × n_inputs (ours is rows × n_inputs × n_outputs).
        let (n_in, n_out) = (a.n_inputs, a.n_outputs);
        let mut attributions = Vec::with_capacity(a.values.len());
        for o in 0..a.n_obs {
            for j in 0..n_out {
                for i in 0..n_in {
                    attributions.push(a.get(o, i, j));
                }
            }
        }
        Ok(Explain_Response {
            success: true,
            message: String::new(),
            attributions,
            input_names: self.explainer.input_names().to_vec(),
            output_names: self.explainer.output_names().to_vec(),
            rows: rows as u32,
        })
    }
}

/// The report as the latched `/explainer/relevance` message (matrices row-major, action ×
/// state).
pub fn relevance_msg(report: &Relevance, header: Header) -> RelevanceMsg {
    RelevanceMsg {
        header,
        experiment: report.experiment.clone(),
        method: report.method.clone(),
        observations: report.observations as u32,
        background: report.background as u32,
        action_names: report.action_names.clone(),
        state_names: report.state_names.clone(),
        mean_abs_shap: report.mean_abs_shap.iter().flatten().copied().collect(),
        state_scale: report.states.iter().map(|s| s.scale).collect(),
        affected: report.states.iter().map(|s| s.affected).collect(),
        threshold: report.threshold,
        rule: report.rule.clone(),
        decision_method: report.decision_method.clone(),
        drives: report.drives.iter().flatten().copied().collect(),
        score: report.decision_score.iter().flatten().copied().collect(),
        interval_lower: report.interval.iter().flatten().map(|i| i[0]).collect(),
        interval_upper: report.interval.iter().flatten().map(|i| i[1]).collect(),
        decision_rule: report.decision_rule.clone(),
        verdict: decision_texts(report, |d| d.verdict.name().to_owned()),
        reason: decision_texts(report, |d| d.reason.clone()),
        to_decide: decision_texts(report, |d| d.to_decide.clone()),
    }
}

/// One text per edge, row-major, from the report's three-valued decisions (none when the
/// report is two-valued).
fn decision_texts(report: &Relevance, text: impl Fn(&Decision) -> String) -> Vec<String> {
    report
        .decisions
        .iter()
        .flatten()
        .flatten()
        .map(text)
        .collect()
}
