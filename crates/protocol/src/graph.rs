//! The data-generation graph as data: its nodes, the parameters they take with defaults,
//! ranges and descriptions, and the topics they publish and subscribe.
//!
//! `launch_scripts/graph.toml` is the one description. `causal-arm launch` and `generate`
//! take their defaults from it, the nodes declare their ROS parameters from it, and the
//! ros2 launch files read the same file, so a default changed there changes everywhere.
//! The file is embedded at build time; `CAUSAL_ARM_GRAPH=FILE` replaces it at run time
//! (for every program of the graph alike, as they inherit the environment).

use std::path::PathBuf;
use std::sync::LazyLock;

use serde::Deserialize;

/// The graph file the programs were built with.
const EMBEDDED: &str = include_str!("../../../launch_scripts/graph.toml");
/// Environment variable naming another graph file to use.
pub const GRAPH_ENV: &str = "CAUSAL_ARM_GRAPH";

/// The graph description.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphSpec {
    /// The run's settings, taken by every node.
    pub run_params: Vec<ParamDecl>,
    /// The nodes, in start order.
    pub nodes: Vec<NodeDecl>,
    /// The serving nodes (trainer, explainer): started by the user on a model directory,
    /// not by `launch`. Their parameters are declared here, and `causal-arm train` and
    /// `explain` take the defaults of the same settings from these declarations.
    #[serde(default)]
    pub servers: Vec<NodeDecl>,
    /// Nodes that take another node's place in a run (`replaces`): the reacher answers
    /// the simulator's states in the babbler's stead when `causal-arm reach` runs the
    /// graph. `launch` does not start them; the graph's readers trust what they publish
    /// as they trust the node they replace.
    #[serde(default)]
    pub stand_ins: Vec<NodeDecl>,
    /// The file it was read from, for errors found later.
    #[serde(skip)]
    source_name: String,
}

/// One node of the graph.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeDecl {
    /// Node and executable name.
    pub name: String,
    /// The run ends when this node exits (the recorder, once the bag is written).
    #[serde(default)]
    pub ends_run: bool,
    /// A stand-in's node whose place it takes (same topics published).
    #[serde(default)]
    pub replaces: Option<String>,
    /// Topics it subscribes to.
    #[serde(default)]
    pub subscribes: Vec<String>,
    /// Topics it publishes.
    #[serde(default)]
    pub publishes: Vec<String>,
    /// Parameters of this node only, beside the run's.
    #[serde(default)]
    pub params: Vec<ParamDecl>,
}

/// One parameter: its type is that of its default.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamDecl {
    /// Name, as given after `-p` and (with `-` for `_`) as a command-line option.
    pub name: String,
    /// Default value.
    pub default: ParamDefault,
    /// One line for `ros2 param describe` and `--help`.
    pub description: String,
    /// Allowed numeric range, inclusive.
    #[serde(default)]
    pub range: Option<[f64; 2]>,
    /// Allowed values of a string parameter.
    #[serde(default)]
    pub choices: Vec<String>,
}

/// A parameter's default, which also fixes its type.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum ParamDefault {
    /// `true` / `false`.
    Bool(bool),
    /// A whole number.
    Integer(i64),
    /// A floating-point number.
    Double(f64),
    /// Text.
    String(String),
    /// A list of texts (`[]` for none).
    StringArray(Vec<String>),
}

impl std::fmt::Display for ParamDefault {
    /// As `-p name:=value` and command-line options write it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Bool(v) => write!(f, "{v}"),
            Self::Integer(v) => write!(f, "{v}"),
            Self::Double(v) => write!(f, "{v:?}"),
            Self::String(v) => f.write_str(v),
            Self::StringArray(v) => write!(f, "[{}]", v.join(", ")),
        }
    }
}

/// Why a graph file is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("graph file {source_name}: {problem}")]
pub struct GraphError {
    /// The file (or "embedded launch_scripts/graph.toml").
    pub source_name: String,
    /// What is wrong, with the place.
    pub problem: String,
}

impl GraphSpec {
    /// Parses and checks a graph description.
    pub fn parse(text: &str, source_name: &str) -> Result<Self, GraphError> {
        let bad = |problem: String| GraphError {
            source_name: source_name.to_owned(),
            problem,
        };
        let mut spec: Self = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        spec.check().map_err(bad)?;
        spec.source_name = source_name.to_owned();
        Ok(spec)
    }

    /// The file it was read from (or "embedded launch_scripts/graph.toml").
    pub fn source_name(&self) -> &str {
        &self.source_name
    }

    /// Reads `CAUSAL_ARM_GRAPH` if set, else the embedded file.
    pub fn load() -> Result<Self, GraphError> {
        match std::env::var_os(GRAPH_ENV) {
            Some(path) => {
                let path = PathBuf::from(path);
                let name = path.display().to_string();
                let text = std::fs::read_to_string(&path).map_err(|e| GraphError {
                    source_name: name.clone(),
                    problem: format!("cannot read ({GRAPH_ENV}): {e}"),
                })?;
                Self::parse(&text, &name)
            }
            None => Self::parse(EMBEDDED, "embedded launch_scripts/graph.toml"),
        }
    }

    /// Every topic named, every name unique, every default in its range and choices.
    fn check(&self) -> Result<(), String> {
        let mut names = std::collections::HashSet::new();
        for node in self.nodes.iter().chain(&self.stand_ins) {
            if !names.insert(node.name.as_str()) {
                return Err(format!("node {} is listed twice", node.name));
            }
            for topic in node.subscribes.iter().chain(&node.publishes) {
                if !crate::topics::ALL.contains(&topic.as_str()) {
                    return Err(format!(
                        "node {}: unknown topic {topic:?} (expected one of {:?})",
                        node.name,
                        crate::topics::ALL
                    ));
                }
            }
            check_params(&node.name, self.run_params.iter().chain(&node.params))?;
        }
        for node in &self.nodes {
            if let Some(other) = &node.replaces {
                return Err(format!(
                    "node {}: only a stand-in replaces a node (it names {other})",
                    node.name
                ));
            }
        }
        for stand_in in &self.stand_ins {
            self.check_stand_in(stand_in)?;
        }
        for server in &self.servers {
            if !names.insert(server.name.as_str()) {
                return Err(format!("node {} is listed twice", server.name));
            }
            if server.ends_run
                || server.replaces.is_some()
                || !server.subscribes.is_empty()
                || !server.publishes.is_empty()
            {
                return Err(format!(
                    "server {}: a server takes only parameters (it is not part of a run)",
                    server.name
                ));
            }
            check_params(&server.name, server.params.iter())?;
        }
        if self.nodes.iter().filter(|n| n.ends_run).count() != 1 {
            return Err("exactly one node must have ends_run = true".into());
        }
        Ok(())
    }

    /// A stand-in names a node of the run and publishes what that node publishes, so
    /// every reader of those topics is served as before.
    fn check_stand_in(&self, stand_in: &NodeDecl) -> Result<(), String> {
        let name = &stand_in.name;
        let replaced = (stand_in.replaces.as_ref())
            .ok_or_else(|| format!("stand-in {name}: `replaces` names no node"))?;
        let node = self
            .nodes
            .iter()
            .find(|n| &n.name == replaced)
            .ok_or_else(|| {
                format!("stand-in {name}: replaces {replaced}, not a node of the run")
            })?;
        let sorted = |t: &[String]| {
            let mut t = t.to_vec();
            t.sort();
            t
        };
        if stand_in.ends_run || sorted(&stand_in.publishes) != sorted(&node.publishes) {
            return Err(format!(
                "stand-in {name}: must publish what {replaced} publishes ({:?}, got {:?}) and not end the run",
                node.publishes, stand_in.publishes
            ));
        }
        Ok(())
    }

    /// The run parameter `name`, or `None` if the graph has none of that name.
    pub fn run_param(&self, name: &str) -> Option<&ParamDecl> {
        self.run_params.iter().find(|p| p.name == name)
    }

    /// The node `name`, of the run or a stand-in.
    pub fn node(&self, name: &str) -> Option<&NodeDecl> {
        (self.nodes.iter().chain(&self.stand_ins)).find(|n| n.name == name)
    }

    /// The nodes publishing `topic`: the run's, and the stand-ins that may take their
    /// place (whose samples the readers take as they take the replaced node's).
    pub fn publishers_of<'a>(&'a self, topic: &'a str) -> impl Iterator<Item = &'a NodeDecl> {
        (self.nodes.iter().chain(&self.stand_ins))
            .filter(move |n| n.publishes.iter().any(|t| t == topic))
    }

    /// The nodes that subscribe `topic`: the readers a publisher must see matched before
    /// its first sample, which a volatile topic would not deliver to a later reader.
    pub fn subscribers_of<'a>(&'a self, topic: &'a str) -> impl Iterator<Item = &'a NodeDecl> {
        self.nodes
            .iter()
            .filter(move |n| n.subscribes.iter().any(|t| t == topic))
    }
}

/// Unique names, defaults within range and choices, ranges only on numbers.
fn check_params<'a>(node: &str, params: impl Iterator<Item = &'a ParamDecl>) -> Result<(), String> {
    let mut seen = std::collections::HashSet::new();
    for p in params {
        let place = format!("node {node}, parameter {}", p.name);
        if !seen.insert(p.name.as_str()) {
            return Err(format!("{place}: declared twice"));
        }
        let number = match p.default {
            ParamDefault::Integer(v) => Some(v as f64),
            ParamDefault::Double(v) => Some(v),
            _ => None,
        };
        match (p.range, number) {
            (Some([lo, hi]), Some(v)) if !(lo <= v && v <= hi) => {
                return Err(format!(
                    "{place}: default {v} outside its range [{lo}, {hi}]"
                ));
            }
            (Some(_), None) => return Err(format!("{place}: a range needs a numeric default")),
            _ => {}
        }
        if !p.choices.is_empty() && !p.choices.contains(&p.default.to_string()) {
            return Err(format!(
                "{place}: default {} is not one of {:?}",
                p.default, p.choices
            ));
        }
    }
    Ok(())
}

static GRAPH: LazyLock<Result<GraphSpec, GraphError>> = LazyLock::new(GraphSpec::load);

/// The graph every program of this run uses (loaded once).
pub fn graph() -> Result<&'static GraphSpec, GraphError> {
    GRAPH.as_ref().map_err(GraphError::clone)
}

/// Owner of the run parameters in the table of [`default_text`] (no node has this name).
const RUN: &str = "";

/// The default of parameter `param` of `owner` ("" for a run parameter, else the node's,
/// stand-in's or server's name) in the graph file in use, as text: a command-line option's
/// default for the same setting (`--help` shows it). Every default is rendered once; ""
/// for a name the graph lacks (the typed modules of `causal_arm_params` only ask for
/// names the program was built with).
pub fn default_text(owner: &str, param: &str) -> &'static str {
    static TEXTS: LazyLock<Vec<(String, String, String)>> = LazyLock::new(|| match graph() {
        Ok(g) => {
            let run = g.run_params.iter().map(|p| (RUN, p));
            let servers =
                (g.servers.iter()).flat_map(|s| s.params.iter().map(|p| (s.name.as_str(), p)));
            let nodes = (g.nodes.iter().chain(&g.stand_ins))
                .flat_map(|n| n.params.iter().map(|p| (n.name.as_str(), p)));
            run.chain(servers)
                .chain(nodes)
                .map(|(o, p)| (o.to_owned(), p.name.clone(), p.default.to_string()))
                .collect()
        }
        Err(_) => Vec::new(),
    });
    TEXTS
        .iter()
        .find(|(o, p, _)| o == owner && p == param)
        .map(|(_, _, v)| v.as_str())
        .unwrap_or("")
}

/// The graph's default of a numeric run parameter, or NaN when the graph cannot be read
/// or has no such number (validation then refuses the run, naming the parameter).
pub fn run_default_f64(name: &str) -> f64 {
    match graph()
        .ok()
        .and_then(|g| g.run_param(name))
        .map(|p| &p.default)
    {
        Some(ParamDefault::Double(v)) => *v,
        Some(ParamDefault::Integer(v)) => *v as f64,
        _ => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_graph_parses_and_names_known_topics() {
        let g = GraphSpec::parse(EMBEDDED, "embedded").unwrap();
        let names: Vec<&str> = g.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "causal_arm_recorder",
                "causal_arm_babbler",
                "causal_arm_sim"
            ]
        );
        assert_eq!(
            g.run_param("sigma").unwrap().default,
            ParamDefault::Double(0.35)
        );
        assert!(g.node("causal_arm_recorder").unwrap().ends_run);
        let readers = |t| {
            let mut names: Vec<&str> = g.subscribers_of(t).map(|n| n.name.as_str()).collect();
            names.sort();
            names
        };
        assert_eq!(
            readers(crate::topics::ACTION),
            ["causal_arm_recorder", "causal_arm_sim"]
        );
        assert_eq!(readers(crate::topics::TF), ["causal_arm_recorder"]);
        // The reacher stands in for the babbler: trusted on its topic, never a reader
        // the run waits for.
        let writers: Vec<&str> = (g.publishers_of(crate::topics::ACTION))
            .map(|n| n.name.as_str())
            .collect();
        assert_eq!(writers, ["causal_arm_babbler", "causal_arm_reacher"]);
        assert_eq!(
            g.node("causal_arm_reacher").unwrap().replaces.as_deref(),
            Some("causal_arm_babbler")
        );
        // Every topic published is subscribed by someone, and the other way round.
        for node in &g.nodes {
            for t in &node.subscribes {
                assert!(
                    g.nodes.iter().any(|n| n.publishes.contains(t)),
                    "{} subscribes to {t}, which nobody publishes",
                    node.name
                );
            }
        }
    }

    #[test]
    fn bad_graph_files_are_refused_with_the_place() {
        let cases = [
            ("nodes = []", "missing field `run_params`"),
            (
                "run_params = []\n[[nodes]]\nname = \"a\"\nends_run = true\nsubscribes = [\"/nope\"]",
                "node a: unknown topic \"/nope\"",
            ),
            (
                "[[run_params]]\nname = \"sigma\"\ndefault = 20.0\nrange = [0.0, 10.0]\ndescription = \"\"\n[[nodes]]\nname = \"a\"\nends_run = true",
                "node a, parameter sigma: default 20 outside its range [0, 10]",
            ),
            (
                "[[run_params]]\nname = \"p\"\ndefault = \"x\"\nchoices = [\"a\"]\ndescription = \"\"\n[[nodes]]\nname = \"a\"\nends_run = true",
                "node a, parameter p: default x is not one of [\"a\"]",
            ),
            (
                "run_params = []\n[[nodes]]\nname = \"a\"",
                "exactly one node must have ends_run = true",
            ),
            (
                "run_params = []\nnodes = []\nextra = 1",
                "unknown field `extra`",
            ),
            (
                "run_params = []\n[[nodes]]\nname = \"a\"\nends_run = true\n[[stand_ins]]\nname = \"b\"\nreplaces = \"c\"",
                "stand-in b: replaces c, not a node of the run",
            ),
            (
                "run_params = []\n[[nodes]]\nname = \"a\"\nends_run = true\npublishes = [\"/clock\"]\n[[stand_ins]]\nname = \"b\"\nreplaces = \"a\"",
                "stand-in b: must publish what a publishes ([\"/clock\"], got [])",
            ),
            (
                "run_params = []\n[[nodes]]\nname = \"a\"\nends_run = true\n[[stand_ins]]\nname = \"b\"",
                "stand-in b: `replaces` names no node",
            ),
        ];
        for (text, expected) in cases {
            let err = GraphSpec::parse(text, "g.toml").unwrap_err().to_string();
            assert!(
                err.starts_with("graph file g.toml: ") && err.contains(expected),
                "{text:?}: {err}"
            );
        }
    }

    #[test]
    fn defaults_print_as_ros_parameters_write_them() {
        assert_eq!(ParamDefault::Double(1.0).to_string(), "1.0");
        assert_eq!(ParamDefault::Double(0.35).to_string(), "0.35");
        assert_eq!(ParamDefault::Integer(0).to_string(), "0");
        assert_eq!(ParamDefault::Bool(true).to_string(), "true");
        assert_eq!(default_text(RUN, "sigma"), "0.35");
        assert_eq!(default_text(RUN, "profile"), "quick");
        assert_eq!(run_default_f64("sigma"), 0.35);
        assert!(run_default_f64("profile").is_nan());
    }
}
