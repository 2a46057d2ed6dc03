//! Built datasets cached as safetensors, keyed by the bag's content hash, so re-training
//! does not decode the bag again (the paper's exp 2 bag holds 16M messages).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use safetensors::{Dtype, SafeTensors, tensor::TensorView};

use crate::build::hash_bag;
use crate::{ActionSource, BagSource, Dataset, DatasetError, Experiment, from_bag};

/// Bumped whenever the data model or the file layout changes, so old files are rebuilt.
const FORMAT: &str = "causal_arm.dataset.v3";

/// Whether a bag's dataset came from the cache.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from a cache file.
    Hit,
    /// Decoded from the bag (and written to the cache if one is used).
    Built,
}

/// A directory of cached datasets.
#[derive(Debug, Clone)]
pub struct Cache {
    dir: PathBuf,
}

impl Cache {
    /// Cache in `dir` (created on first write).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// `$CAUSAL_ARM_CACHE`, else `$XDG_CACHE_HOME/causal-arm`, else `~/.cache/causal-arm`.
    pub fn default_dir() -> PathBuf {
        if let Some(dir) = std::env::var_os("CAUSAL_ARM_CACHE") {
            return PathBuf::from(dir);
        }
        let base = std::env::var_os("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
            .unwrap_or_else(std::env::temp_dir);
        base.join("causal-arm")
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn file_for(&self, hash: &str, action: ActionSource) -> PathBuf {
        self.dir.join(format!(
            "dataset-{}-{action}-{FORMAT}.safetensors",
            &hash[..32]
        ))
    }

    /// The bag's dataset from the cache, or built from the bag and stored.
    pub fn load_or_build(
        &self,
        bag: &Path,
        expected: Option<Experiment>,
        action: ActionSource,
    ) -> Result<(Dataset, CacheOutcome), DatasetError> {
        let reader = causal_arm_bag::BagReader::open(bag)?;
        let hash = hash_bag(&reader)?;
        drop(reader);
        let file = self.file_for(&hash, action);
        if file.exists() {
            match read(&file) {
                Ok(mut data) => {
                    if let Some(expected) = expected
                        && data.experiment != expected
                    {
                        return Err(DatasetError::WrongExperiment {
                            bag: bag.to_owned(),
                            found: data.experiment,
                            expected,
                            how: "cached dataset of this bag".into(),
                        });
                    }
                    data.sources = vec![BagSource {
                        path: bag.display().to_string(),
                        blake3: hash,
                        rows: data.rows(),
                    }];
                    return Ok((data, CacheOutcome::Hit));
                }
                Err(e) => tracing::warn!("ignoring unreadable cache entry: {e}"),
            }
        }
        let data = from_bag(bag, expected, action)?;
        if let Err(e) = write(&data, &file) {
            tracing::warn!("dataset not cached: {e}");
        }
        Ok((data, CacheOutcome::Built))
    }
}

/// Loads several bags as one dataset (same experiment), through `cache` when given. A
/// shard set stands for its shards, in order; each bag's episodes stay its own, so no
/// transition crosses from one bag or shard into the next. Says how each bag was read.
pub fn load_bags(
    bags: &[PathBuf],
    expected: Option<Experiment>,
    action: ActionSource,
    cache: Option<&Cache>,
) -> Result<(Dataset, Vec<(PathBuf, CacheOutcome)>), DatasetError> {
    let mut outcomes = Vec::new();
    let mut all: Option<Dataset> = None;
    for bag in expand_shard_sets(bags)? {
        let (data, outcome) = match cache {
            Some(cache) => cache.load_or_build(&bag, expected, action)?,
            None => (from_bag(&bag, expected, action)?, CacheOutcome::Built),
        };
        outcomes.push((bag, outcome));
        match &mut all {
            None => all = Some(data),
            Some(all) => all.append(data)?,
        }
    }
    let data = all.ok_or_else(|| DatasetError::Mixed("no bags given".into()))?;
    Ok((data, outcomes))
}

/// The bags `paths` stand for, shard sets replaced by their shards.
pub fn expand_shard_sets(paths: &[PathBuf]) -> Result<Vec<PathBuf>, DatasetError> {
    let mut bags = Vec::new();
    for path in paths {
        bags.extend(causal_arm_bag::bags_in(path)?);
    }
    Ok(bags)
}

fn cache_err(path: &Path, problem: impl std::fmt::Display) -> DatasetError {
    DatasetError::Cache {
        path: path.to_owned(),
        problem: problem.to_string(),
    }
}

/// Writes `data` as a safetensors file in the cache's layout (`states`, `actions`,
/// `next_states`, `episodes`, `holding`, `steps`, `stamps_ns`, and `randomized` where the
/// bags record their design; the experiment in the
/// metadata), for tools outside the project (numpy, the causal-discovery anchors).
/// Atomic: a reader sees the whole file or none.
pub fn write_safetensors(data: &Dataset, path: &Path) -> Result<(), DatasetError> {
    write(data, path)
}

/// Writes atomically (temp file + rename) so a crash never leaves a half file behind.
fn write(data: &Dataset, path: &Path) -> Result<(), DatasetError> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| cache_err(dir, e))?;
    let (rows, sw, aw) = (data.rows(), data.state_width(), data.action_width());
    fn view<'a>(
        dtype: Dtype,
        shape: Vec<usize>,
        bytes: &'a [u8],
        path: &Path,
    ) -> Result<TensorView<'a>, DatasetError> {
        TensorView::new(dtype, shape, bytes).map_err(|e| cache_err(path, e))
    }
    let mut tensors = vec![
        (
            "actions",
            view(
                Dtype::F32,
                vec![rows, aw],
                bytemuck::cast_slice(&data.actions),
                path,
            )?,
        ),
        (
            "episodes",
            view(
                Dtype::U32,
                vec![rows],
                bytemuck::cast_slice(&data.episodes),
                path,
            )?,
        ),
        ("holding", view(Dtype::U8, vec![rows], &data.holding, path)?),
        (
            "next_states",
            view(
                Dtype::F32,
                vec![rows, sw],
                bytemuck::cast_slice(&data.next_states),
                path,
            )?,
        ),
        (
            "stamps_ns",
            view(
                Dtype::U64,
                vec![rows],
                bytemuck::cast_slice(&data.stamps_ns),
                path,
            )?,
        ),
        (
            "states",
            view(
                Dtype::F32,
                vec![rows, sw],
                bytemuck::cast_slice(&data.states),
                path,
            )?,
        ),
        (
            "steps",
            view(
                Dtype::U32,
                vec![rows],
                bytemuck::cast_slice(&data.steps),
                path,
            )?,
        ),
    ];
    if let Some(randomized) = &data.randomized {
        let bytes = bytemuck::cast_slice(randomized);
        tensors.push(("randomized", view(Dtype::U32, vec![rows], bytes, path)?));
    }
    let metadata = HashMap::from([
        ("format".to_owned(), FORMAT.to_owned()),
        ("experiment".to_owned(), data.experiment.to_string()),
        ("action_source".to_owned(), data.action_source.to_string()),
    ]);
    let tmp = path.with_extension("tmp");
    safetensors::serialize_to_file(tensors, Some(metadata), &tmp)
        .map_err(|e| cache_err(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| cache_err(path, e))?;
    Ok(())
}

fn read(path: &Path) -> Result<Dataset, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| cache_err(path, e))?;
    let (_, header) = SafeTensors::read_metadata(&bytes).map_err(|e| cache_err(path, e))?;
    let meta = header.metadata().clone().unwrap_or_default();
    if meta.get("format").map(String::as_str) != Some(FORMAT) {
        return Err(cache_err(path, "not a dataset of this version"));
    }
    let parse = |key: &str| {
        meta.get(key)
            .cloned()
            .ok_or_else(|| cache_err(path, format!("no {key} in metadata")))
    };
    let experiment: Experiment = parse("experiment")?
        .parse()
        .map_err(|e| cache_err(path, e))?;
    let action_source: ActionSource = parse("action_source")?
        .parse()
        .map_err(|e| cache_err(path, e))?;
    let tensors = SafeTensors::deserialize(&bytes).map_err(|e| cache_err(path, e))?;
    fn get<T: bytemuck::Pod>(
        t: &SafeTensors,
        name: &str,
        dtype: Dtype,
        path: &Path,
    ) -> Result<Vec<T>, DatasetError> {
        let view = t.tensor(name).map_err(|e| cache_err(path, e))?;
        if view.dtype() != dtype {
            return Err(cache_err(
                path,
                format!("{name} is {:?}, expected {dtype:?}", view.dtype()),
            ));
        }
        // Copy: the file buffer gives no alignment guarantee.
        Ok(bytemuck::pod_collect_to_vec(view.data()))
    }
    let data = Dataset {
        experiment,
        action_source,
        states: get(&tensors, "states", Dtype::F32, path)?,
        actions: get(&tensors, "actions", Dtype::F32, path)?,
        next_states: get(&tensors, "next_states", Dtype::F32, path)?,
        episodes: get(&tensors, "episodes", Dtype::U32, path)?,
        holding: get(&tensors, "holding", Dtype::U8, path)?,
        steps: get(&tensors, "steps", Dtype::U32, path)?,
        stamps_ns: get(&tensors, "stamps_ns", Dtype::U64, path)?,
        randomized: match tensors.names().contains(&"randomized") {
            true => Some(get(&tensors, "randomized", Dtype::U32, path)?),
            false => None,
        },
        sources: Vec::new(),
    };
    let rows = data.rows();
    if data.states.len() != rows * data.state_width()
        || data.next_states.len() != rows * data.state_width()
        || data.actions.len() != rows * data.action_width()
        || data.steps.len() != rows
        || data.holding.len() != rows
        || data.stamps_ns.len() != rows
        || data.randomized.as_ref().is_some_and(|r| r.len() != rows)
    {
        return Err(cache_err(path, "tensor shapes disagree"));
    }
    Ok(data)
}
