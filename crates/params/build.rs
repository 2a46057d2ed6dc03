//! Makes the typed parameter structs from launch_scripts/graph.toml (see src/codegen.rs).

#[path = "src/codegen.rs"]
#[allow(dead_code)]
mod codegen;

fn main() {
    let graph =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../launch_scripts/graph.toml");
    println!("cargo::rerun-if-changed={}", graph.display());
    let text = std::fs::read_to_string(&graph)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", graph.display()));
    let code = codegen::generate(&text).unwrap_or_else(|e| panic!("{}: {e}", graph.display()));
    let out = std::path::Path::new(&std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("declared.rs");
    std::fs::write(&out, code).unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
}
