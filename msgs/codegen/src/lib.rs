//! Build-time generator of the `causal_arm_msgs` Rust types from ROS 2 `.msg` / `.srv` files.
//!
//! The interface files are the single source of truth: ROS 2 users compile them with rosidl,
//! and this crate compiles the very same files into Rust, so the two sides cannot drift. The
//! parser is deliberately strict and reports `file:line: problem (expected ...)` so a typo
//! fails the Rust build instead of producing types that disagree with rclpy.

use std::fmt;
use std::path::{Path, PathBuf};

pub mod emit;
pub mod parse;
pub mod type_hash;

pub use emit::{generate, generate_at};
pub use type_hash::{FieldDescription, TypeHashError, TypeIndex};

pub use parse::{
    ArrayKind, BaseType, Constant, Field, FieldType, MessageSpec, ParseError, ServiceSpec, Value,
    parse_message, parse_service,
};

/// One parsed interface file.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)] // a few dozen per build; boxing buys nothing
pub enum Interface {
    /// A `.msg` file.
    Message {
        /// Path of the source file, for error messages.
        file: String,
        /// The parsed message.
        spec: MessageSpec,
    },
    /// A `.srv` file.
    Service {
        /// Path of the source file, for error messages.
        file: String,
        /// The parsed service.
        spec: ServiceSpec,
    },
}

/// Anything that stops generation; all variants name the file or type involved.
#[derive(Debug)]
pub enum Error {
    /// Reading an interface file or directory failed.
    Io {
        /// The path that could not be read.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file is not valid interface language.
    Parse(ParseError),
    /// Two files define the same type.
    Duplicate {
        /// The type defined twice.
        ros_type: String,
        /// The second file defining it.
        file: String,
    },
    /// A message contains itself (directly or through others).
    Recursive(String),
    /// A type's REP-2011 hash needs a definition that was not given.
    TypeHash(TypeHashError),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Parse(e) => e.fmt(f),
            Error::Duplicate { ros_type, file } => {
                write!(f, "{file}: type {ros_type} is defined twice")
            }
            Error::Recursive(chain) => write!(f, "recursive message definition: {chain}"),
            Error::TypeHash(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Parse(e) => Some(e),
            _ => None,
        }
    }
}

impl From<ParseError> for Error {
    fn from(e: ParseError) -> Self {
        Error::Parse(e)
    }
}

fn list(dir: &Path, ext: &str) -> Result<Vec<PathBuf>, Error> {
    if !dir.exists() {
        return Ok(Vec::new());
    }
    let rd = std::fs::read_dir(dir).map_err(|source| Error::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut files = Vec::new();
    for entry in rd {
        let entry = entry.map_err(|source| Error::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        let p = entry.path();
        if p.extension().is_some_and(|e| e == ext) {
            files.push(p);
        }
    }
    files.sort();
    Ok(files)
}

/// Parse `dir/msg/*.msg` and `dir/srv/*.srv` of ROS package `package` (the layout of a ROS
/// interface package, so the same directory is what colcon builds).
pub fn load_package(package: &str, dir: &Path) -> Result<Vec<Interface>, Error> {
    let mut out = Vec::new();
    for (sub, ext) in [("msg", "msg"), ("srv", "srv")] {
        for path in list(&dir.join(sub), ext)? {
            let text = std::fs::read_to_string(&path).map_err(|source| Error::Io {
                path: path.clone(),
                source,
            })?;
            let name = path
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or_default()
                .to_string();
            let file = path.display().to_string();
            out.push(if ext == "msg" {
                Interface::Message {
                    spec: parse_message(package, &name, &file, &text)?,
                    file,
                }
            } else {
                Interface::Service {
                    spec: parse_service(package, &name, &file, &text)?,
                    file,
                }
            });
        }
    }
    Ok(out)
}

/// Interfaces of several packages collected by a build script, then emitted together so
/// cross-package references resolve.
#[derive(Debug, Default)]
pub struct InterfaceSet {
    interfaces: Vec<Interface>,
}

impl InterfaceSet {
    /// Parse the `msg/` and `srv/` files of `package` below `dir`; returns the files read so
    /// the build script can ask cargo to rerun when one changes.
    pub fn add_package_dir(&mut self, package: &str, dir: &Path) -> Result<Vec<PathBuf>, Error> {
        let files = interface_files(dir)?;
        self.interfaces.extend(load_package(package, dir)?);
        Ok(files)
    }

    /// The parsed interfaces so far.
    pub fn interfaces(&self) -> &[Interface] {
        &self.interfaces
    }

    /// Rust source for everything added; `own_package` lands in the crate-root `msg`/`srv`.
    pub fn emit_rust(&self, own_package: &str) -> Result<String, Error> {
        generate(own_package, &self.interfaces)
    }

    /// Like [`InterfaceSet::emit_rust`] for a file included in module `root`, not the crate root.
    pub fn emit_rust_at(&self, own_package: &str, root: &str) -> Result<String, Error> {
        generate_at(own_package, &self.interfaces, root)
    }
}

/// All input files below `dir` (for `cargo:rerun-if-changed`).
pub fn interface_files(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let mut out = Vec::new();
    for sub in ["msg", "srv"] {
        out.extend(list(&dir.join(sub), sub)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
