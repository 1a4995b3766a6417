//! Generates the Rust types of the `rover_msgs` interfaces from `msg/*.msg`, so the two cannot drift.

#[path = "src/idl.rs"]
#[allow(dead_code, unreachable_pub)]
mod idl;

use std::fmt::Write as _;
use std::path::Path;

const PACKAGE: &str = "rover_msgs";

fn main() {
    println!("cargo:rerun-if-changed=msg");
    let mut names: Vec<_> = std::fs::read_dir("msg")
        .expect("msg/ directory")
        .map(|entry| entry.expect("msg/ entry").path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "msg"))
        .collect();
    names.sort();
    let mut code = String::new();
    for path in &names {
        let name = path.file_stem().and_then(|s| s.to_str()).expect("utf-8 file name");
        let text = std::fs::read_to_string(path).expect("readable .msg file");
        let spec = idl::parse_msg(PACKAGE, &text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        write_message(&mut code, name, &spec);
    }
    let out = Path::new(&std::env::var("OUT_DIR").expect("OUT_DIR")).join("rover_msgs.rs");
    std::fs::write(out, code).expect("write generated code");
}

fn write_message(code: &mut String, name: &str, spec: &idl::MessageSpec) {
    let _ = writeln!(code, "ros_message! {{");
    for line in &spec.doc {
        let _ = writeln!(code, "    #[doc = {line:?}]");
    }
    let _ = writeln!(code, "    {PACKAGE:?} / {name} {{");
    for field in &spec.fields {
        for line in &field.doc {
            let _ = writeln!(code, "        #[doc = {line:?}]");
        }
        if field.ros_type == "uint8[]" {
            let _ = writeln!(code, "        #[serde(with = \"serde_bytes\")]");
        }
        let _ = writeln!(code, "        {}: {},", rust_field_name(&field.name), rust_type(&field.ros_type));
    }
    let _ = writeln!(code, "    }}");
    let _ = writeln!(code, "}}");
    if !spec.constants.is_empty() {
        let _ = writeln!(code, "impl {name} {{");
        for constant in &spec.constants {
            let _ = writeln!(code, "    #[doc = \"Constant `{}` of `{name}.msg`.\"]", constant.name);
            let value = if constant.ros_type == "string" {
                format!("{:?}", constant.value.trim_matches(|c| c == '"' || c == '\''))
            } else {
                constant.value.clone()
            };
            let ty = if constant.ros_type == "string" { "&str".to_string() } else { rust_type(&constant.ros_type) };
            let _ = writeln!(code, "    pub const {}: {ty} = {value};", constant.name);
        }
        let _ = writeln!(code, "}}");
    }
}

fn rust_field_name(name: &str) -> String {
    match name {
        "type" | "match" | "ref" | "move" | "static" | "struct" | "enum" | "fn" => {
            format!("r#{name}")
        }
        other => other.to_string(),
    }
}

fn rust_type(ros_type: &str) -> String {
    if let Some(element) = ros_type.strip_suffix("[]") {
        return format!("Vec<{}>", rust_type(element));
    }
    if let Some((element, len)) = ros_type.strip_suffix(']').and_then(|t| t.rsplit_once('[')) {
        return format!("[{}; {len}]", rust_type(element));
    }
    match ros_type {
        "bool" => "bool".into(),
        "int8" => "i8".into(),
        "uint8" => "u8".into(),
        "int16" => "i16".into(),
        "uint16" => "u16".into(),
        "int32" => "i32".into(),
        "uint32" => "u32".into(),
        "int64" => "i64".into(),
        "uint64" => "u64".into(),
        "float32" => "f32".into(),
        "float64" => "f64".into(),
        "string" => "String".into(),
        qualified => {
            let (package, name) = qualified.split_once('/').expect("qualified message type");
            let module = if package == PACKAGE { "msg" } else { package };
            format!("crate::{module}::{name}")
        }
    }
}
