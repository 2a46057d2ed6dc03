//! The package modules of the generated file and the registry that lists their types
//! (`MESSAGE_TYPES`, `SERVICE_TYPES`, `dispatch`, `visit_known`).

use std::fmt::Write as _;

use super::Registry;
use super::rust::doc_attr;
use crate::parse::{MessageSpec, ServiceSpec};

/// What the generated registry lists: (ROS_TYPE, Rust path) of every message type and
/// service half, and every service type.
#[derive(Default)]
pub(super) struct TypeTables {
    types: Vec<(String, String)>,
    services: Vec<String>,
}

impl TypeTables {
    /// `MESSAGE_TYPES`, `SERVICE_TYPES`, `dispatch` and `visit_known`.
    pub(super) fn emit(&self, out: &mut String) {
        out.push_str(
            "/// Every `ROS_TYPE` of the generated message types (service halves included).\n",
        );
        out.push_str("pub(crate) const MESSAGE_TYPES: &[&str] = &[\n");
        for (t, _) in &self.types {
            let _ = writeln!(out, "    {t:?},");
        }
        out.push_str("];\n\n/// Every generated service `ROS_TYPE`.\npub(crate) const SERVICE_TYPES: &[&str] = &[\n");
        for t in &self.services {
            let _ = writeln!(out, "    {t:?},");
        }
        out.push_str("];\n\n");
        out.push_str(
            "/// Call `v.visit::<M>()` for the type whose `ROS_TYPE` is exactly `ros_type`; give `v` back otherwise.\n\
             pub(crate) fn dispatch<V: crate::MessageTypeVisitor>(ros_type: &str, v: V) -> Result<V::Output, V> {\n    match ros_type {\n",
        );
        for (t, path) in &self.types {
            let _ = writeln!(out, "        {t:?} => Ok(v.visit::<{path}>()),");
        }
        out.push_str("        _ => Err(v),\n    }\n}\n\n");
        out.push_str(
            "/// Like `dispatch`, but also accepts the short form `pkg/Name` (message first, then service half).\n\
             pub(crate) fn visit_known<V: crate::MessageTypeVisitor>(ros_type: &str, v: V) -> Option<V::Output> {\n\
             \x20   let v = match dispatch(ros_type, v) {\n\
             \x20       Ok(out) => return Some(out),\n\
             \x20       Err(v) => v,\n\
             \x20   };\n\
             \x20   let (pkg, name) = ros_type.split_once('/')?;\n\
             \x20   if name.contains('/') {\n\
             \x20       return None;\n\
             \x20   }\n\
             \x20   let v = match dispatch(&format!(\"{pkg}/msg/{name}\"), v) {\n\
             \x20       Ok(out) => return Some(out),\n\
             \x20       Err(v) => v,\n\
             \x20   };\n\
             \x20   dispatch(&format!(\"{pkg}/srv/{name}\"), v).ok()\n\
             }\n",
        );
    }
}

impl Registry<'_> {
    /// One package's module: its messages and services, recorded in `tables`.
    pub(super) fn emit_package(
        &mut self,
        out: &mut String,
        pkg: &str,
        msgs: &[&MessageSpec],
        srvs: &[&ServiceSpec],
        tables: &mut TypeTables,
    ) {
        let own = pkg == self.own;
        let root = self.root;
        if !own {
            doc_attr(
                out,
                "",
                &[format!(
                    "Types of the ROS 2 package `{pkg}` (copied .msg files, Jazzy)."
                )],
            );
            let _ = writeln!(out, "pub mod {pkg} {{");
        }
        if !msgs.is_empty() {
            doc_attr(out, "", &[format!("Messages of `{pkg}` (`{pkg}/msg/*`).")]);
            out.push_str("pub mod msg {\n");
            for m in msgs.iter() {
                self.emit_struct(
                    out,
                    m,
                    "msg",
                    &format!("ROS 2 message `{}/msg/{}`.", m.package, m.name),
                );
                let path = if own {
                    format!("{root}::msg::{}", m.name)
                } else {
                    format!("{root}::{pkg}::msg::{}", m.name)
                };
                tables.types.push((format!("{pkg}/msg/{}", m.name), path));
            }
            out.push_str("}\n\n");
        }
        if !srvs.is_empty() {
            doc_attr(out, "", &[format!("Services of `{pkg}` (`{pkg}/srv/*`).")]);
            out.push_str("pub mod srv {\n");
            for s in srvs.iter() {
                self.emit_service(out, s);
                let base = if own {
                    format!("{root}::srv")
                } else {
                    format!("{root}::{pkg}::srv")
                };
                for half in ["Request", "Response"] {
                    tables.types.push((
                        format!("{pkg}/srv/{}_{half}", s.name),
                        format!("{base}::{}_{half}", s.name),
                    ));
                }
                tables.services.push(format!("{pkg}/srv/{}", s.name));
            }
            out.push_str("}\n\n");
        }
        if !own {
            out.push_str("}\n\n");
        }
    }
}
