//! Generates the Rust types from `msg/`, `srv/` and the vendored standard definitions
//! in `ros_interfaces/`, so Rust and the ROS 2 interface package cannot drift.
//! Also generates `tests/fixtures/` (every generator feature) for the unit tests.

use std::path::{Path, PathBuf};

use causal_arm_msgs_codegen::{Error, InterfaceSet};

fn package_dirs(root: &Path) -> Vec<PathBuf> {
    let mut dirs: Vec<_> = std::fs::read_dir(root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    dirs
}

fn add_all(set: &mut InterfaceSet, root: &Path, inputs: &mut Vec<PathBuf>) -> Result<(), Error> {
    for dir in package_dirs(root) {
        let package = dir
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_owned();
        inputs.extend(set.add_package_dir(&package, &dir)?);
    }
    Ok(())
}

fn write(name: &str, code: &str) {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("OUT_DIR")).join(name);
    std::fs::write(&out, code).unwrap_or_else(|e| panic!("{}: {e}", out.display()));
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut inputs = Vec::new();

    let mut set = InterfaceSet::default();
    let real = add_all(&mut set, &root.join("ros_interfaces"), &mut inputs)
        .and_then(|()| {
            inputs.extend(set.add_package_dir("causal_arm_msgs", root)?);
            set.emit_rust("causal_arm_msgs")
        })
        .unwrap_or_else(|e| panic!("interface generation failed: {e}"));
    write("interfaces.rs", &real);

    // Test fixture: its own set (plus the standard types it references), rooted at
    // `crate::fixture`, so it never shows up in the real registry.
    let mut fixture = InterfaceSet::default();
    let fixture_code = add_all(&mut fixture, &root.join("ros_interfaces"), &mut inputs)
        .and_then(|()| add_all(&mut fixture, &root.join("tests/fixtures"), &mut inputs))
        .and_then(|()| fixture.emit_rust_at("causal_arm_msgs", "crate::fixture"))
        .unwrap_or_else(|e| panic!("fixture generation failed: {e}"));
    write("fixture.rs", &fixture_code);

    for path in &inputs {
        println!("cargo:rerun-if-changed={}", path.display());
    }
    for dir in ["msg", "srv", "ros_interfaces", "tests/fixtures"] {
        println!("cargo:rerun-if-changed={dir}");
    }
}
