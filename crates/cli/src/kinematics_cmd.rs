//! `causal-arm fk` / `causal-arm ik`: kinematics of the iiwa URDF from the command line,
//! as JSON, so users and the PyBullet oracle test can check the arm model.

use std::io::{BufRead as _, Write as _};
use std::path::PathBuf;

use anyhow::{Context as _, bail};
use causal_arm_kinematics::{ArmModel, IkOptions, IkTarget};
use clap::Args;
use serde::Serialize;

/// Arguments of `causal-arm fk`.
#[derive(Debug, Args)]
pub struct FkArgs {
    /// Joint angles in rad, comma separated (7 values, iiwa_joint_1..7).
    #[arg(long, allow_hyphen_values = true, required_unless_present = "batch")]
    joints: Option<String>,
    /// URDF to use instead of the embedded urdf/iiwa14_magnet.urdf.
    #[arg(long)]
    urdf: Option<PathBuf>,
    /// Read one joint vector per stdin line (comma or space separated), print one JSON line each.
    #[arg(long, conflicts_with = "joints")]
    batch: bool,
}

/// Arguments of `causal-arm ik`.
#[derive(Debug, Args)]
pub struct IkArgs {
    /// Target position of ef in the world frame, m: X,Y,Z.
    #[arg(long, allow_hyphen_values = true, required_unless_present = "batch")]
    position: Option<String>,
    /// Also require the tool to point straight down (as for picking from the table).
    #[arg(long)]
    down: bool,
    /// Seed of the random restarts.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// URDF to use instead of the embedded one.
    #[arg(long)]
    urdf: Option<PathBuf>,
    /// Read one X,Y,Z target per stdin line; failures print {"ok":false,"error":…}.
    #[arg(long, conflicts_with = "position")]
    batch: bool,
}

fn load_model(urdf: &Option<PathBuf>) -> anyhow::Result<ArmModel> {
    Ok(match urdf {
        Some(path) => ArmModel::from_urdf_file(path)?,
        None => ArmModel::embedded(),
    })
}

fn parse_numbers(text: &str, what: &str) -> anyhow::Result<Vec<f64>> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .enumerate()
        .map(|(i, s)| {
            s.parse::<f64>()
                .with_context(|| format!("{what}: value {} ({s:?}) is not a number", i + 1))
        })
        .collect()
}

/// Pose of `ef` as printed by `fk`: a struct, not `json!`, so the keys keep this order.
#[derive(Debug, Serialize)]
struct FkOutput {
    position: [f64; 3],
    orientation_xyzw: [f64; 4],
}

/// Result of `ik` for one target, in print order.
#[derive(Debug, Serialize)]
struct IkOutput {
    ok: bool,
    joints: Vec<f64>,
    error_m: f64,
    orientation_error_rad: f64,
    attempts: usize,
}

/// A failed target in `ik --batch`.
#[derive(Debug, Serialize)]
struct IkFailure {
    ok: bool,
    error: String,
}

fn fk_json(model: &ArmModel, text: &str) -> anyhow::Result<String> {
    let q = parse_numbers(text, "--joints")?;
    model.check_joints(&q)?;
    let pose = model.ef_pose(&q)?;
    let t = pose.translation.vector;
    let r = pose.rotation.coords; // x, y, z, w
    Ok(serde_json::to_string(&FkOutput {
        position: [t.x, t.y, t.z],
        orientation_xyzw: [r.x, r.y, r.z, r.w],
    })?)
}

/// Runs `causal-arm fk`.
pub fn run_fk(args: &FkArgs) -> anyhow::Result<()> {
    let model = load_model(&args.urdf)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.batch {
        for (n, line) in std::io::stdin().lock().lines().enumerate() {
            let line = line.context("reading stdin")?;
            if line.trim().is_empty() {
                continue;
            }
            let value = fk_json(&model, &line).with_context(|| format!("stdin line {}", n + 1))?;
            writeln!(out, "{value}")?;
        }
    } else {
        let joints = args.joints.as_deref().unwrap_or_default();
        writeln!(out, "{}", fk_json(&model, joints)?)?;
    }
    Ok(())
}

fn ik_solve(model: &ArmModel, text: &str, down: bool, seed: u64) -> anyhow::Result<String> {
    let p = parse_numbers(text, "--position")?;
    let [x, y, z] = p[..] else {
        bail!("--position needs 3 values X,Y,Z, got {}", p.len());
    };
    let target = if down {
        IkTarget::pointing_down(x, y, z)
    } else {
        IkTarget::position(x, y, z)
    };
    let sol = model.inverse(
        &target,
        &IkOptions {
            seed,
            ..IkOptions::default()
        },
    )?;
    Ok(serde_json::to_string(&IkOutput {
        ok: true,
        joints: sol.joints,
        error_m: sol.position_error_m,
        orientation_error_rad: sol.orientation_error_rad,
        attempts: sol.attempts,
    })?)
}

/// Runs `causal-arm ik`.
pub fn run_ik(args: &IkArgs) -> anyhow::Result<()> {
    let model = load_model(&args.urdf)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.batch {
        for (n, line) in std::io::stdin().lock().lines().enumerate() {
            let line = line.context("reading stdin")?;
            if line.trim().is_empty() {
                continue;
            }
            let value = ik_solve(&model, &line, args.down, args.seed.wrapping_add(n as u64))
                .unwrap_or_else(|e| {
                    serde_json::to_string(&IkFailure {
                        ok: false,
                        error: format!("{e:#}"),
                    })
                    .expect("a string serializes")
                });
            writeln!(out, "{value}")?;
        }
    } else {
        let position = args.position.as_deref().unwrap_or_default();
        writeln!(out, "{}", ik_solve(&model, position, args.down, args.seed)?)?;
    }
    Ok(())
}
